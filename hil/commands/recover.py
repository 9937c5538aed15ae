"""`hil recover LOG [--dry-run] [--json]`: make a bag whose recorder was killed whole again.

Rewrites each truncated split from its complete chunks and lists every split in
``metadata.yaml`` (see :mod:`hil.bag.recover`), so that rosbags, ``ros2 bag``
and Foxglove read everything that reached the disk. With ``--dry-run`` it only
says what it would do and writes nothing. Exit status 0 when done (or nothing to
do), 2 when the log cannot be read or recovered.
"""

from __future__ import annotations

import argparse
import json
import sys

HELP = "Recover a bag left by a killed recorder: rewrite truncated splits, list them."


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare `LOG`, `--dry-run` and `--json`."""
    parser.add_argument("log", metavar="LOG", help="bag directory, or a .mcap file")
    parser.add_argument(
        "--dry-run", action="store_true", help="only say what would be done; write nothing"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    """Recover `args.log` in place (or report with --dry-run); return the exit status."""
    from hil.bag.errors import ReplayError
    from hil.bag.recover import inspect_recovery, recover

    try:
        report = inspect_recovery(args.log) if args.dry_run else recover(args.log)
    except ReplayError as err:
        print(f"hil recover: error: {err}", file=sys.stderr)
        return 2
    if args.json:
        print(
            json.dumps(
                {
                    "path": str(report.path),
                    "dry_run": bool(args.dry_run),
                    "rewritten": list(report.rewritten),
                    "removed": list(report.removed),
                    "messages": report.messages,
                    "problems": list(report.problems),
                }
            )
        )
        return 0
    verb = "would rewrite" if args.dry_run else "rewrote"
    if not report.changed:
        print(f"{report.path}: nothing to recover ({report.messages} messages)")
    for name in report.rewritten:
        print(f"{verb} {name}")
    for name in report.removed:
        print(f"{'would remove' if args.dry_run else 'removed'} {name} (no complete message)")
    for problem in report.problems:
        print(f"  {problem}")
    if report.changed:
        print(f"{report.path}: {report.messages} messages kept")
    return 0
