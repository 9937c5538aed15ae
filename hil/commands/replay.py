"""`hil replay LOG...`: replay recorded runs through the current code and report regressions.

Arguments may be bags, folders of bags and shell globs (``hil replay logs/*``):
what is not a bag (README.md, suite.json, a folder without bags) is skipped with
a one-line note. Each log gets a readable report (decisions, tracking, contract,
stack; resim with ``--resim``); ``--json``, ``--jsonl`` and ``--junit`` give the
same machine-readable. Exit status (:data:`EXIT_CODES`): 0 when no log regressed
(warnings do not count), 1 on any regression, 2 when a log cannot be replayed
(missing, truncated beyond use, foreign, recorded for another scenario) or no
bag was given, even if other logs regressed, with a one-line reason per log.
Logs are only read, never modified.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

from hil.commands.executor_cli import add_executor_arguments, executor_choice
from hil.commands.replay_progress import ReplayProgress
from hil.commands.stages import Stages

if TYPE_CHECKING:
    from hil.replay.controllers import ScenarioCache
    from hil.replay.job import ReplayTask
    from hil.replay.options import ReplayOptions
    from hil.replay.regression import LogReport

HELP = "replay recorded runs through the current code; non-zero exit on any regression"

EXIT_CODES = """exit status:
  0  no regression: every log replayed and none failed (warnings do not count)
  1  regression: some check failed in some log
  2  unreadable input: some log could not be replayed (missing, foreign, truncated
     beyond use, another scenario), or no bag among the arguments; this wins over 1
     when some logs regress and others are unreadable (both are reported)

Arguments that are not bags (README.md, suite.json, a folder without bags) are
skipped with a one-line note; a folder holding bags stands for its bags."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EXIT_CODES
    parser.add_argument(
        "logs",
        nargs="+",
        type=Path,
        metavar="LOG",
        help="bag directory, .mcap/.db3 file or folder of bags (several allowed, e.g. logs/*)",
    )
    parser.add_argument(
        "--json", action="store_true", help="end with a JSON summary of every log on the last line"
    )
    parser.add_argument(
        "--jsonl",
        type=Path,
        default=None,
        metavar="FILE",
        help="also write FILE: one JSON line per judged interval between decisions "
        "(decision, containment, tracking error, verdict), one per log, and the "
        "overall verdict on the last line ('-' for stdout)",
    )
    parser.add_argument(
        "--junit", type=Path, default=None, metavar="FILE", help="also write JUnit XML for CI"
    )
    parser.add_argument(
        "--tolerance",
        default="",
        metavar="K=V,...",
        help="thresholds: surge=, sway= (m/s), yaw= (deg/s) tracking RMS "
        "(enforced on the axes given; by default none: the RMS is a figure, shown beside "
        "the paper's tank figures); "
        "rel= relative tracking difference to the recording (0.05); "
        "surge_max=, sway_max=, yaw_max= largest error; "
        "estimate=, command= re-run differences; position= resim (m)",
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
        help="replay with this scenario instead of the one each log names (needed for a "
        "bag holding only the lab's topics)",
    )
    parser.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="FILE",
        help="vessel config (TOML, as for `hil vessel`): the lab's topic names, the arena "
        "transform and the loop rate for bags holding only the lab's topics (default: the "
        "lab's topics, identity transform, 20 Hz)",
    )
    add_executor_arguments(parser, 1)


_BAG_SUFFIXES = (".mcap", ".db3")
_MAGIC = (b"\x89MCAP", b"SQLite format 3\x00")


def _holds_splits(folder: Path) -> bool:
    """Whether `folder` is a bag itself: metadata.yaml or storage files in it."""
    return (folder / "metadata.yaml").exists() or any(
        p.suffix.lower() in _BAG_SUFFIXES for p in folder.iterdir() if p.is_file()
    )


def _is_bag_file(path: Path) -> bool:
    """Whether `path` is a storage file: by its suffix, else by its first bytes."""
    if path.suffix.lower() in _BAG_SUFFIXES:
        return True
    try:
        with path.open("rb") as f:
            head = f.read(16)
    except OSError:
        return True  # unreadable: let the replay say why, as an error
    return head.startswith(_MAGIC)


def expand(paths: list[Path]) -> tuple[list[Path], list[tuple[Path, str]]]:
    """Return (logs to replay, (path, why) skipped).

    A bag directory or storage file is a log; a folder holding bags (directly) stands
    for them; a path that does not exist is kept, so that its replay says so (exit 2).
    Anything else (a README, a manifest, a folder without bags) is skipped.
    """
    logs: list[Path] = []
    skipped: list[tuple[Path, str]] = []
    for path in paths:
        if not path.exists():
            logs.append(path)
        elif path.is_dir():
            if _holds_splits(path):
                logs.append(path)
                continue
            bags = sorted(d for d in path.iterdir() if d.is_dir() and _holds_splits(d))
            logs.extend(bags)
            if not bags:
                skipped.append((path, "a folder without bags"))
        elif _is_bag_file(path):
            logs.append(path)
        else:
            skipped.append((path, "not a bag"))
    return logs, skipped


def _one_line(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return text[0] if text else type(err).__name__


def _write_replay_rrd(
    log: Path, folder: Path, caches: ScenarioCache, options: ReplayOptions, report: LogReport
) -> str:
    """Write the recording with its replayed decisions to an .rrd; return what happened.

    A lab bag's recording gets the scenario's layout and the decisions its stack
    re-run took (kept in the report); a hil log's, its decisions taken again.
    """
    from hil.bag.errors import ReplayError
    from hil.bag.run_data import load_run
    from hil.replay.controllers import resolve_scenario
    from hil.replay.decisions import replayed_decisions
    from hil.replay.lab import lab_topics, with_scenario_layout
    from hil.views.rerun_export import write_rrd

    out = folder / f"{log.name}.replay.rrd"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        recorded = load_run(log, options.lab or lab_topics()).require_motion()
        chosen = resolve_scenario(recorded, options.scenario)
        if recorded.lab_only:
            recorded = with_scenario_layout(recorded, chosen)
            replayed = list(report.replayed)
        else:
            replayed = replayed_decisions(recorded, caches.get(chosen))
        stats = write_rrd(recorded, out, chosen, None, replayed=replayed)
    except (ReplayError, ValueError, OSError) as err:
        return f"not written: {_one_line(err)}"
    return f"{out} ({stats.bytes / 1e6:.1f} MB)"


def _open_jsonl(target: Path) -> TextIO:
    """Open the --jsonl target ('-' is stdout)."""
    if str(target) == "-":
        return sys.stdout
    target.parent.mkdir(parents=True, exist_ok=True)
    return target.open("w", encoding="utf-8")


def _replay_here(progress: ReplayProgress, task: ReplayTask) -> LogReport:
    """Replay `task` in this process, showing the log's current step on `progress`."""
    from hil.replay.job import process_caches, replay_task
    from hil.replay.replayer import replay_log

    if task.files is not None:  # shipped bytes: the worker's path, no steps to show
        return replay_task(task)
    caches = process_caches(task.options.cache_dir)
    return replay_log(task.path, task.options, caches, progress=progress.step(Path(task.path)))


def _replay_options(args: argparse.Namespace) -> ReplayOptions:
    """Return the replay's options from the command line.

    Raises:
        ValueError: A bad --tolerance, --pose-delay-ms or --config.
    """
    from hil.adapters.log import LogConfig
    from hil.replay.lab import load_lab_config
    from hil.replay.options import ReplayOptions, Tolerance

    tolerance = Tolerance.parse(args.tolerance)
    log_config = LogConfig(pose_delay_ns=round(args.pose_delay_ms * 1e6))
    lab, lab_loop = load_lab_config(args.config)
    return ReplayOptions(
        tolerance=tolerance,
        stack=not args.no_stack,
        resim=args.resim,
        scenario=args.scenario,
        log=log_config,
        intervals=args.jsonl is not None,
        lab=lab,
        lab_loop=lab_loop,
    )


@dataclasses.dataclass
class _InOrderPrinter:
    """Prints each finished log's report in argument order, as the replays end in any order.

    Attributes:
        logs: The logs being replayed, in order.
        emit: Where the readable reports go (stdout, or stderr when stdout carries JSON).
        progress: The progress display, told of each log done.
        jsonl: The --jsonl stream, or None.
        rerun: The --rerun folder, or None.
        caches: The scenario caches of this process (for --rerun).
        options: The replay's options (for --rerun).
        reports: The reports printed so far, in order.
    """

    logs: list[Path]
    emit: Callable[[str], None]
    progress: ReplayProgress
    jsonl: TextIO | None
    rerun: Path | None
    caches: ScenarioCache
    options: ReplayOptions
    reports: list[LogReport] = dataclasses.field(default_factory=list)
    _done: dict[int, LogReport] = dataclasses.field(default_factory=dict)

    def __call__(self, index: int, outcome: object) -> None:
        """Keep a finished log; print every log up to the first still running, in order."""
        from hil.replay.regression import LogReport, jsonl_lines, render
        from hil.runs.fanout import Failure

        if isinstance(outcome, Failure):  # the last guard: one line, never a traceback
            outcome = LogReport(str(self.logs[index]), error=f"internal error: {outcome.error}")
        assert isinstance(outcome, LogReport)
        self._done[index] = outcome
        self.progress.done()
        while len(self.reports) in self._done:
            path, report = self.logs[len(self.reports)], self._done.pop(len(self.reports))
            self.reports.append(report)
            self.emit(render(report))
            if self.rerun is not None and not report.error:
                written = _write_replay_rrd(path, self.rerun, self.caches, self.options, report)
                self.emit(f"  rerun: {written}")
            if report.error:
                print(f"hil replay: error: {report.path}: {report.error}", file=sys.stderr)
            if self.jsonl is not None:
                self.jsonl.write("".join(line + "\n" for line in jsonl_lines(report)))
                self.jsonl.flush()


def _finish(
    args: argparse.Namespace,
    reports: list[LogReport],
    jsonl: TextIO | None,
    emit: Callable[[str], None],
) -> int:
    """Write --junit and the --jsonl verdict, print the verdict and --json; return the status."""
    from hil.replay.regression import (
        exit_code,
        junit_xml,
        summary_json,
        verdict_jsonl,
        verdict_line,
    )

    code = exit_code(reports)
    if args.junit is not None:
        try:
            args.junit.write_text(junit_xml(reports))
        except OSError as err:
            where = repr(str(args.junit))
            print(f"hil replay: error: cannot write {where}: {_one_line(err)}", file=sys.stderr)
            code = max(code, 2)
    if jsonl is not None:
        jsonl.write(verdict_jsonl(reports) + "\n")
        if jsonl is not sys.stdout:
            jsonl.close()
    emit(verdict_line(reports))
    if args.json:
        print(summary_json(reports))
    return code


def run(args: argparse.Namespace) -> int:
    """Replay every log, print the reports; return 0, 1 (regression) or 2 (bad log)."""
    Stages("hil replay").say(f"replaying {len(args.logs)} log argument(s) ...")
    from hil.replay.job import REPLAY_JOB, process_caches, task_for
    from hil.runs.backends import open_executor, require_backend
    from hil.runs.errors import ExecutorError
    from hil.runs.fanout import fan_out

    choice = executor_choice(args)
    try:
        require_backend(choice)
        options = _replay_options(args)
    except (ValueError, ExecutorError) as err:
        print(f"hil replay: error: {_one_line(err)}", file=sys.stderr)
        return 2
    jsonl: TextIO | None = None
    if args.jsonl is not None:
        try:
            jsonl = _open_jsonl(args.jsonl)
        except OSError as err:
            where = repr(str(args.jsonl))
            print(f"hil replay: error: cannot write {where}: {_one_line(err)}", file=sys.stderr)
            return 2
    # The reports go to stdout, or to stderr when stdout carries JSON.
    to_stderr = args.json or (jsonl is sys.stdout)

    def emit(text: str) -> None:
        print(text, file=sys.stderr if to_stderr else sys.stdout, flush=True)

    caches = process_caches()  # shared with the replays run in this process
    logs, skipped = expand(list(args.logs))
    for path, why in skipped:
        emit(f"skipped {path}: {why}")
    if not logs:
        print(
            f"hil replay: error: no bag among {len(args.logs)} argument(s) "
            f"({', '.join(str(p) for p in args.logs[:3])}{', ...' if len(args.logs) > 3 else ''})",
            file=sys.stderr,
        )
    tasks = [task_for(path, options, ship=choice.scheduler is not None) for path in logs]
    try:
        executor = open_executor(choice, REPLAY_JOB.warm)
    except ExecutorError as err:
        print(f"hil replay: error: {err}", file=sys.stderr)
        return 2
    # Only a replay in this process can show each log's step; workers report logs done.
    progress = ReplayProgress(len(logs))
    printer = _InOrderPrinter(logs, emit, progress, jsonl, args.rerun, caches, options)
    here = choice.scheduler is None and not choice.dask and choice.workers == 1
    job = REPLAY_JOB
    if here:
        job = dataclasses.replace(REPLAY_JOB, run=functools.partial(_replay_here, progress))
    with progress, executor:
        if executor.dashboard:
            emit(f"Dask dashboard: {executor.dashboard}")
        outcome = fan_out(job, tasks, executor, report=printer)
    if outcome.stopped:
        print(f"hil replay: {outcome.stopped}: {len(printer.reports)} of {len(logs)} logs "
              "replayed", file=sys.stderr)
        if not printer.reports:
            return 2
    return _finish(args, printer.reports, jsonl, emit)
