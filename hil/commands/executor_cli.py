"""What the fanning-out commands share: executor and results options, progress, failures.

``hil campaign``, ``hil sweep``, ``hil replay`` and ``hil record-suite`` run their
jobs through :func:`hil.runs.fanout.fan_out`; this module gives them the same
options (``--workers N``, ``--dask``, ``--scheduler tcp://HOST:PORT``, and for the
campaigns ``--results FILE`` / ``--resume FILE``), the same progress bar (runs done,
rate, ETA; Dask's dashboard link above it) and the same report of failed runs.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rich.console import Console
    from rich.progress import Progress, Task, TaskID
    from rich.text import Text

    from hil.runs.backends import ExecutorChoice
    from hil.runs.campaign import CampaignResult, CampaignRun
    from hil.runs.fanout import Failure, Job
    from hil.runs.results import Plan, ResultStream
    from hil.runs.sim_run import SimRunSpec


def add_executor_arguments(parser: argparse.ArgumentParser, default_workers: int | None) -> None:
    """Declare ``--workers``, ``--dask`` and ``--scheduler``.

    Args:
        parser: The command's parser.
        default_workers: Local processes by default; None: all cores.
    """
    workers = default_workers or os.cpu_count() or 1
    parser.add_argument("--workers", type=int, default=workers, metavar="N",
                        help=f"parallel processes, local or of a local Dask cluster "
                             f"(default: {'all cores' if default_workers is None else workers})")
    parser.add_argument("--dask", action="store_true",
                        help="run on a local Dask cluster of --workers processes "
                             "(needs the extra: pip install 'hil[dask]')")
    parser.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                        help="run on the Dask cluster of this scheduler (dask scheduler; "
                             "dask worker tcp://HOST:PORT --nthreads 1 on each machine)")


def add_results_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare ``--results FILE`` and ``--resume FILE``."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--results", type=Path, default=None, metavar="FILE",
                       help="stream one JSON line per finished run to FILE (default: "
                            "runs/<command>-<scenario>-<time>.jsonl)")
    group.add_argument("--resume", type=Path, default=None, metavar="FILE",
                       help="continue the campaign of results FILE (same arguments): its "
                            "finished runs are read back, the others run")


def executor_choice(args: argparse.Namespace) -> ExecutorChoice:
    """Return the executor the arguments ask for."""
    from hil.runs.backends import ExecutorChoice

    return ExecutorChoice(args.workers, args.dask, args.scheduler)


def open_stream(args: argparse.Namespace, plan: Plan, stem: str) -> ResultStream:
    """Open the results file of ``--results``/``--resume`` (default: a new one under runs/).

    Raises:
        ResultsError: As :meth:`hil.runs.results.ResultStream.open`.
    """
    from hil.runs.results import ResultStream

    if args.resume is not None:
        return ResultStream(args.resume, plan, resume=True).open()
    path = args.results or Path("runs") / f"{stem}-{time.strftime('%Y%m%d-%H%M%S')}.jsonl"
    return ResultStream(path, plan).open()


class RunProgress:
    """A progress bar of runs: done of total, rate (runs/s), elapsed and ETA.

    On a terminal only, unless `enabled`; the dashboard link is printed above it.

    Args:
        console: Where to draw.
        label: What runs ("coarse: docking runs").
        total: Runs planned.
        done: Runs already done (read back on resume).
        dashboard: Link printed first, when there is one.
        enabled: Draw the bar; default when the console is a terminal.
    """

    def __init__(self, console: Console, label: str, total: int, done: int = 0,
                 dashboard: str | None = None, enabled: bool | None = None) -> None:
        self.console = console
        self.label = label
        self.total = total
        self.done = done
        self.failed = 0
        self.dashboard = dashboard
        self.enabled = console.is_terminal if enabled is None else enabled
        self._progress: Progress | None = None
        self._task: TaskID | None = None

    def __enter__(self) -> RunProgress:
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            ProgressColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )
        from rich.text import Text

        class Rate(ProgressColumn):
            def render(self, task: Task) -> Text:
                speed = task.speed
                return Text("-- runs/s" if speed is None else f"{speed:.2f} runs/s")

        if self.dashboard:
            self.console.print(f"Dask dashboard: {self.dashboard}")
        if self.enabled:
            self._progress = Progress(
                "[progress.description]{task.description}", BarColumn(), MofNCompleteColumn(),
                Rate(), TimeElapsedColumn(), "ETA", TimeRemainingColumn(), console=self.console)
            self._progress.__enter__()
            self._task = self._progress.add_task(self.label, total=self.total,
                                                 completed=self.done)
        return self

    def advance(self, _index: int, outcome: Any) -> None:
        """Count one run as ended (a :data:`hil.runs.fanout.Report`)."""
        from hil.runs.fanout import Failure

        self.done += 1
        if isinstance(outcome, Failure):
            self.failed += 1
            self.console.print(f"run {outcome.index} FAILED: {outcome.error}")
        if self._progress is not None and self._task is not None:
            failed = f" ({self.failed} failed)" if self.failed else ""
            self._progress.update(self._task, advance=1, description=self.label + failed)

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 traceback: TracebackType | None) -> None:
        if self._progress is not None:
            self._progress.__exit__(kind, value, traceback)
            self._progress = None


def failure_lines(command: str, failures: list[Failure], results: Path | None) -> list[str]:
    """Return one line per failed run with its spec, and how to re-run them."""
    lines = [f"hil {command}: run {f.index} failed: {f.error}; spec: "
             f"{json.dumps(f.spec, sort_keys=True)}" for f in failures]
    if failures and results is not None:
        lines.append(f"hil {command}: {len(failures)} run(s) failed; re-run only them with the "
                     f"same arguments and --resume {results}")
    return lines


def run_specs(args: argparse.Namespace, command: str, stem: str, specs: list[SimRunSpec],
              job: Job[SimRunSpec, CampaignRun], console: Console,
              label: str) -> tuple[CampaignResult, Path] | int:
    """Run simulated docking specs on the executor `args` chose, streamed to a results file.

    What ``hil campaign`` and ``hil sweep`` share: the results file (``--results``,
    ``--resume``; named from `stem` by default), the executor, the progress bar (titled
    `label` and the executor) and the fan-out.

    Returns:
        The campaign's result and its results file, or 2 after printing why the results
        file or the executor could not be opened.
    """
    import sys

    from hil.runs.backends import open_executor
    from hil.runs.campaign import run_campaign
    from hil.runs.errors import ExecutorError, ResultsError
    from hil.runs.results import Plan

    try:
        stream = open_stream(args, Plan.of(command, [job.encode_spec(s) for s in specs]), stem)
    except ResultsError as err:
        print(f"hil {command}: {err}", file=sys.stderr)
        return 2
    with stream:
        try:
            executor = open_executor(executor_choice(args), job.warm)
        except ExecutorError as err:
            print(f"hil {command}: {err}", file=sys.stderr)
            return 2
        with executor, RunProgress(console, f"{label} ({executor.description})", len(specs),
                                   len(stream.finished), executor.dashboard) as progress:
            result = run_campaign(specs, executor, stream=stream, job=job,
                                  report=progress.advance)
    return result, stream.path
