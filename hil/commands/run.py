"""`hil run [SCENARIO]`: dock the simulated vessel, record the run, print a summary.

With no arguments it docks the simulated C/S Voyager in the paper's scenario,
records every message as a rosbag2 (MCAP) directory under `runs/`, and prints
the summary; `--json` adds the same as one JSON object on the last line.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from hil.commands.common import (
    EXIT_ABORTED,
    EXIT_BAD_INPUT,
    EXIT_DOCKED,
    EXIT_NOT_DOCKED,
    live_rerun,
    missing_display,
    non_negative_int,
    positive_factor,
    positive_seconds,
    start_pose,
)
from hil.commands.stages import Stages

if TYPE_CHECKING:
    from hil.runtime.protocols import RunLog
    from hil.scenarios import Scenario

HELP = "dock the vessel in simulation (or over ROS 2), record the run and summarize it"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.add_argument("scenario", nargs="?", default="paper", metavar="SCENARIO",
                        help="packaged name (paper, coarse) or a .toml path (default: paper)")
    parser.add_argument("--seed", type=non_negative_int, default=0,
                        help="seed of the simulated world")
    parser.add_argument("--start", type=start_pose, default=None, metavar="X,Y,PSI_DEG",
                        help="start pose (m, m, deg); default: right of the arena, bow up")
    parser.add_argument("--backend", choices=("sim",), default="sim",
                        help="world to run in (the vessel's ROS entry point is `hil vessel`)")
    parser.add_argument("--out", type=Path, default=None, metavar="DIR",
                        help="bag directory to create (default: runs/<scenario>-<time>)")
    parser.add_argument("--no-record", action="store_true", help="keep the run in memory only")
    parser.add_argument("--max-duration", type=positive_seconds, default=600.0, metavar="S",
                        help="give up after this many simulated seconds")
    parser.add_argument("--rerun", nargs="?", const="spawn", default=None, metavar="RRD",
                        help="stream the run live to Rerun: a spawned viewer, or into RRD")
    parser.add_argument("--synthesis-latency", type=positive_seconds, default=None,
                        metavar="S", help="model a slower solver: each synthesis takes S "
                        "simulated seconds, one at a time, as beside the vessel's loop "
                        "(default: at once)")
    parser.add_argument("--pose-noise-scale", type=positive_factor, default=1.0, metavar="K",
                        help="the simulated motion capture K times noisier than the 1 mm / "
                        "0.1 deg the EKF assumes (above 1 the estimation premise breaks and "
                        "the consistency watch should stop the vessel)")
    parser.add_argument("--json", action="store_true",
                        help="end with the summary as one JSON object on the last line")


def run(args: argparse.Namespace) -> int:
    """Run, print the summary; exit status as in :mod:`hil.commands.common`.

    0 docked, 1 not docked (time limit, or stopped by SIGINT/SIGTERM: the loop stops at
    its next tick, zero thrust, the log complete and named on the console), 2 bad input
    (before anything ran), 3 aborted (synthesis failed, or the start has no safe input).
    """
    stages = Stages("hil run")
    stages.say(f"scenario {args.scenario} (seed {args.seed}): loading the simulator and the "
               "controller's tables")
    from rich.console import Console

    from hil.bag.errors import ReplayError
    from hil.commands.run_progress import StageLog
    from hil.controllers.symbolic import SymbolicError
    from hil.runs.sim_run import SimRunSpec, run_in_sim
    from hil.runs.stack_assembly import default_start
    from hil.runtime.settings import LoopConfig
    from hil.scenarios import ScenarioError, check_start, load_scenario

    console = Console(stderr=args.json)
    if args.rerun == "spawn" and (headless := missing_display()) is not None:
        print(f"hil run: error: --rerun needs a viewer window but there is {headless}: "
              "stream into a file instead (--rerun run.rrd)", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        scenario = load_scenario(args.scenario)
        check_start(scenario, *(args.start or default_start(scenario)))
    except ScenarioError as err:
        print(f"hil run: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    name = scenario.name
    out = None
    if not args.no_record:
        stamp = time.strftime("%Y%m%d-%H%M%S")
        out = args.out or Path("runs") / f"{name}-seed{args.seed}-{stamp}"
    spec = SimRunSpec(scenario=args.scenario, seed=args.seed, start=args.start, out_dir=out,
                      loop=LoopConfig(max_duration_s=args.max_duration),
                      synthesis_latency_s=args.synthesis_latency or 0.0,
                      pose_noise_scale=args.pose_noise_scale)
    rerun = None if args.rerun is None else live_rerun(args.rerun)
    what = f"{name}, seed {args.seed}"
    try:
        with console.status(f"starting {what} ...") as status:

            def live(scenario: Scenario, inner: RunLog) -> RunLog:
                inner = inner if rerun is None else rerun(scenario, inner)
                return StageLog(inner, status.update, what)

            summary = run_in_sim(spec, live=live, handle_signals=True)
    except (ScenarioError, SymbolicError, ReplayError, ValueError) as err:
        print(f"hil run: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except MemoryError as err:
        print(f"hil run: error: not enough memory for the {name!r} grid ({err}): "
              "use a coarser [grid] cell_m or fewer heading_cells", file=sys.stderr)
        return EXIT_BAD_INPUT
    summary.render(console)
    stages.say(f"done in {stages.total_s():.1f} s")
    where = f"log: {summary.log or 'not recorded'}"
    if summary.aborted:
        print(f"hil run: aborted: {summary.end_reason} ({where})", file=sys.stderr)
    elif summary.end_reason.startswith("stopped by"):
        print(f"hil run: {summary.end_reason}; the run is recorded up to the stop ({where})",
              file=sys.stderr)
    if args.json:
        print(summary.to_json())
    if summary.docked:
        return EXIT_DOCKED
    return EXIT_ABORTED if summary.aborted else EXIT_NOT_DOCKED
