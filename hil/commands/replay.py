"""`hil replay LOG...`: replay recorded runs through the current code and report regressions.

Each log gets a readable report (decisions, tracking, margin, stack; resim
with ``--resim``). Exit status: 0 when every log reproduces, 1 on any
regression, 2 when a log cannot be replayed (missing, truncated beyond use,
foreign, recorded for another scenario), with a one-line reason per log.
Logs are only read, never modified.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from hil.replay.controllers import ScenarioCache

HELP = "replay recorded runs through the current code; non-zero exit on any regression"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.add_argument(
        "logs",
        nargs="+",
        type=Path,
        metavar="LOG",
        help="bag directory or .mcap file (several allowed, e.g. logs/*)",
    )
    parser.add_argument(
        "--json", action="store_true", help="end with a JSON summary of every log on the last line"
    )
    parser.add_argument(
        "--junit", type=Path, default=None, metavar="FILE", help="also write JUnit XML for CI"
    )
    parser.add_argument(
        "--tolerance",
        default="",
        metavar="K=V,...",
        help="thresholds: surge=, sway= (m/s), yaw= (deg/s) tracking RMS "
        "(enforced when given; default the paper's tank figures, advisory); "
        "rel= relative tracking difference to the recording (0.05); "
        "surge_max=, sway_max=, yaw_max= largest error; "
        "estimate=, command= re-run differences; position= resim (m); "
        "settle= margin check skips this long after each decision "
        "(s, default 1)",
    )
    parser.add_argument(
        "--resim", action="store_true", help="also re-simulate each run (closed loop) and compare"
    )
    parser.add_argument(
        "--no-stack",
        action="store_true",
        help="skip re-running the full stack on the recorded streams",
    )
    parser.add_argument(
        "--pose-delay-ms",
        type=float,
        default=10.0,
        metavar="MS",
        help="delivery delay of recorded poses in the stack re-run (default 10, "
        "the simulated motion-capture latency)",
    )
    parser.add_argument(
        "--rerun",
        type=Path,
        default=None,
        metavar="DIR",
        help="also write DIR/<log>.replay.rrd: the recording with the replayed decisions "
        "beside it and every difference marked (open with `rerun FILE`)",
    )
    parser.add_argument(
        "--scenario",
        default=None,
        metavar="SCENARIO",
        help="replay with this scenario instead of the one each log names",
    )


# Files a shell glob such as `logs/*` brings along that are not logs: skipped, not errors.
_NOT_LOGS = {".md", ".json", ".txt", ".toml", ".rrd", ".png"}


def _expand(paths: list[Path]) -> tuple[list[Path], list[Path]]:
    """Return (logs to replay, files skipped): a folder of bags stands for its bags."""
    logs: list[Path] = []
    skipped: list[Path] = []
    for path in paths:
        if path.is_file() and path.suffix.lower() in _NOT_LOGS:
            skipped.append(path)
        elif path.is_dir() and not (path / "metadata.yaml").exists() and not any(
            path.glob("*.mcap")
        ) and not any(path.glob("*.db3")):
            bags = sorted(d for d in path.iterdir() if (d / "metadata.yaml").is_file())
            logs.extend(bags or [path])
        else:
            logs.append(path)
    return logs, skipped


def _one_line(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return text[0] if text else type(err).__name__


def _write_replay_rrd(
    log: Path, folder: Path, caches: ScenarioCache, scenario: str | None
) -> str:
    """Write the recording with its replayed decisions to an .rrd; return what happened."""
    from hil.bag.errors import ReplayError
    from hil.bag.run_data import load_run
    from hil.replay.controllers import resolve_scenario
    from hil.replay.decisions import replayed_decisions
    from hil.views.rerun_export import write_rrd

    out = folder / f"{log.name}.replay.rrd"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        recorded = load_run(log).require_motion()
        chosen = resolve_scenario(recorded, scenario)
        replayed = replayed_decisions(recorded, caches.get(chosen))
        stats = write_rrd(recorded, out, chosen, None, replayed=replayed)
    except (ReplayError, ValueError, OSError) as err:
        return f"not written: {_one_line(err)}"
    return f"{out} ({stats.bytes / 1e6:.1f} MB)"


def run(args: argparse.Namespace) -> int:
    """Replay every log, print the reports; return 0, 1 (regression) or 2 (bad log)."""
    from hil.adapters.log import LogConfig
    from hil.replay.controllers import ScenarioCache
    from hil.replay.options import ReplayOptions, Tolerance
    from hil.replay.regression import exit_code, junit_xml, render, summary_json
    from hil.replay.replayer import replay_log

    try:
        tolerance = Tolerance.parse(args.tolerance)
        log_config = LogConfig(pose_delay_ns=round(args.pose_delay_ms * 1e6))
    except ValueError as err:
        print(f"hil replay: {_one_line(err)}", file=sys.stderr)
        return 2
    options = ReplayOptions(
        tolerance=tolerance,
        stack=not args.no_stack,
        resim=args.resim,
        scenario=args.scenario,
        log=log_config,
    )
    caches = ScenarioCache()
    reports = []
    out = sys.stderr if args.json else sys.stdout
    logs, skipped = _expand(list(args.logs))
    for path in skipped:
        print(f"skipped {path}: not a log", file=out)
    for path in logs:
        try:
            report = replay_log(path, options, caches)
        except Exception as err:  # the last guard: one line, never a traceback
            from hil.replay.regression import LogReport

            report = LogReport(
                str(path), error=f"internal error: {type(err).__name__}: {_one_line(err)}"
            )
        reports.append(report)
        print(render(report), file=out, flush=True)
        if args.rerun is not None and not report.error:
            written = _write_replay_rrd(path, args.rerun, caches, args.scenario)
            print(f"  rerun: {written}", file=out, flush=True)
        if report.error:
            print(f"hil replay: {report.path}: {report.error}", file=sys.stderr)
    code = exit_code(reports)
    if args.junit is not None:
        try:
            args.junit.write_text(junit_xml(reports))
        except OSError as err:
            print(
                f"hil replay: cannot write {str(args.junit)!r}: {_one_line(err)}", file=sys.stderr
            )
            code = max(code, 2)
    verdict = {0: "no regression", 1: "REGRESSION", 2: "ERROR: some logs could not be replayed"}
    print(f"{len(reports)} log(s): {verdict[code]}", file=out)
    if args.json:
        print(summary_json(reports))
    return code
