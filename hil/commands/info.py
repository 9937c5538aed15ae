"""`hil info LOG [--json]`: describe a recorded run (or any rosbag2 / MCAP log).

Prints the topics, their types and counts, the time span, what produced the run
and any damage found. Never modifies the log. A log that cannot be read gets a
one-line error on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import json
import sys

HELP = "Describe a recorded run: topics, counts, time span, scenario and damage."


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare `LOG` and `--json`."""
    parser.add_argument("log", metavar="LOG", help="bag directory, or a .mcap / .db3 file")
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object instead of the text summary"
    )
    parser.add_argument(
        "--check",
        action="store_true",
        help="also decode every message and report the ones that do not decode (exit 1 if any)",
    )


def _seconds(t_ns: int | None) -> str:
    if t_ns is None:
        return "-"
    sec, nsec = divmod(t_ns, 1_000_000_000)
    return f"{sec}.{nsec:09d} s"


def format_info(info: object) -> str:
    """Return the readable summary of a :class:`hil.bag.reader.BagInfo`."""
    from hil.bag.reader import BagInfo

    assert isinstance(info, BagInfo)
    kind = "rosbag2" if info.path.is_dir() else "file"
    lines = [
        f"log:       {info.path}  ({kind}, {info.storage}, {len(info.files)} file(s))",
        f"messages:  {info.message_count}",
        f"duration:  {info.duration_ns / 1e9:.3f} s  "
        f"(start {_seconds(info.start_ns)}, end {_seconds(info.end_ns)})",
    ]
    run = info.run
    if run is not None:
        seed = "-" if run.seed is None else str(run.seed)
        lines.append(
            f"run:       scenario {run.scenario_file or '-'} (hash {run.scenario_hash or '-'}), "
            f"seed {seed}, backend {run.backend or '-'}, hil {run.hil_version or '-'}, "
            f"git {run.git_revision[:12] or '-'}"
        )
    elif info.custom:
        lines.append(f"custom:    {info.custom!r}")
    if info.topics:
        width = max(len(t.name) for t in info.topics)
        type_width = max(len(t.msgtype) for t in info.topics)
        lines.append("topics:")
        for t in info.topics:
            note = "" if t.decodable else f"  (not decodable: {t.problem})"
            lines.append(
                f"  {t.name:<{width}}  {t.msgtype:<{type_width}}  {t.message_count:>8}{note}"
            )
    else:
        lines.append("topics:    none")
    if info.problems:
        lines.append("problems:")
        lines.extend(f"  {p}" for p in info.problems)
    if not info.is_hil_run:
        lines.append("note:      not a hil run: none of hil's topics")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Print the summary of `args.log`.

    Returns:
        0; 1 with ``--check`` when a message does not decode; 2 when the log
        cannot be read at all.
    """
    from hil.bag.errors import BagError
    from hil.bag.reader import BagReader

    skipped: list[str] = []
    try:
        with BagReader(args.log) as reader:
            info = reader.info
            if args.check:
                decodable = [t.name for t in info.topics if t.decodable]
                for _ in reader.decoded(decodable, on_error="skip"):
                    pass
                skipped = [s.reason for s in reader.skipped]
    except BagError as err:
        print(f"hil info: error: {err}", file=sys.stderr)
        return 2
    if args.json:
        data = info.to_dict()
        if args.check:
            data["undecodable"] = skipped
        print(json.dumps(data))
    else:
        print(format_info(info))
        if args.check:
            print(f"check:     {len(skipped)} message(s) do not decode")
            for reason in skipped[:20]:
                print(f"  {reason}")
    return 1 if skipped else 0
