"""`hil sweep FILE`: a grid or random sample of simulated runs from a TOML file, in parallel.

Scenarios, seeds, starts, start velocities, PID gains and disturbance levels
(:mod:`hil.runs.sweep` describes the file). Runs like ``hil campaign``: local
processes by default, a Dask cluster with ``--dask`` or ``--scheduler``, each
finished run streamed to a results file (``--resume FILE`` continues); prints the
campaign's report over all runs, then docked runs and docking time per value of
every axis that varies. Exit status as ``hil campaign``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from hil.commands.executor_cli import (
    add_executor_arguments,
    add_results_arguments,
    executor_choice,
    run_specs,
)
from hil.commands.stages import Stages

if TYPE_CHECKING:
    from rich.console import Console

    from hil.runs.campaign import CampaignResult
    from hil.runs.sweep import SweepPoint

HELP = "run a grid or random sample over scenarios, seeds, starts, gains, disturbances"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.add_argument("file", type=Path, metavar="FILE", help="the sweep (TOML)")
    add_executor_arguments(parser, None)
    add_results_arguments(parser)
    parser.add_argument("--list", action="store_true",
                        help="list the runs (one JSON spec a line) and exit")
    parser.add_argument("--json", action="store_true",
                        help="end with the figures as one JSON object on the last line")


def _by_axis(console: Console, points: list[SweepPoint], outcome: CampaignResult) -> None:
    """Print docked runs and docking time per value of each axis with several values."""
    from rich.table import Table

    from hil.runs.sweep import AXES

    labels = {id(p.spec): p.labels for p in points}
    table = Table(title="per axis value (finished runs)")
    for column in ("axis", "value", "runs", "docked", "docking time mean"):
        table.add_column(column, justify="left" if column in ("axis", "value") else "right")
    for axis in AXES:
        values = sorted({p.labels[axis] for p in points})
        if len(values) < 2:
            continue
        for value in values:
            runs = [summary for (summary, _), spec in zip(outcome.runs, outcome.specs,
                                                          strict=True)
                    if labels[id(spec)][axis] == value]
            times = [s.docking_time_s for s in runs if s.docked and s.docking_time_s]
            mean = f"{sum(times) / len(times) / 60:.2f} min" if times else "-"
            table.add_row(axis, value, str(len(runs)), str(sum(s.docked for s in runs)), mean)
    if table.row_count:
        console.print(table)


def run(args: argparse.Namespace) -> int:
    """Run the sweep; return the exit status (as ``hil campaign``)."""
    Stages("hil sweep").say(f"reading {args.file} and loading the simulator ...")
    import json

    from rich.console import Console

    from hil.commands.campaign_report import report
    from hil.runs.backends import require_backend
    from hil.runs.campaign import sim_job
    from hil.runs.errors import ExecutorError
    from hil.runs.sweep import SweepError, load_sweep

    if args.workers < 1:
        print("hil sweep: error: --workers must be at least 1", file=sys.stderr)
        return 2
    try:
        require_backend(executor_choice(args))
        sweep = load_sweep(args.file)
        points = sweep.points()
    except (ExecutorError, SweepError) as err:
        print(f"hil sweep: error: {err}", file=sys.stderr)
        return 2
    specs = [p.spec for p in points]
    job = sim_job("sweep", sweep.scenarios)
    encoded = [job.encode_spec(s) for s in specs]
    if args.list:
        for spec in encoded:
            print(json.dumps(spec, sort_keys=True))
        return 0
    console = Console(stderr=args.json)
    ran = run_specs(args, "sweep", f"sweep-{args.file.stem}", specs, job, console,
                    f"{args.file.name}: {sweep.mode} of {len(specs)} runs")
    if isinstance(ran, int):
        return ran
    outcome, results = ran
    status = report(outcome, command="sweep", console=console, as_json=args.json,
                    title=f"sweep {args.file.name} ({sweep.mode})",
                    extra={"sweep": str(args.file), "mode": sweep.mode},
                    results=results)
    if outcome.runs:
        _by_axis(console, points, outcome)
    return status
