"""`hil campaign [SCENARIO] -n N [--workers K]`: Monte Carlo over random starts and seeds.

Prints the success rate, the docking-time distribution beside the paper's tank
figures, the least hull clearance and the tracking error; `--json` adds them as
one JSON object on the last line.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from dataclasses import asdict

from hil.commands.common import positive_seconds

HELP = "run many simulated dockings from random starts in parallel and compare with the paper"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.add_argument("scenario", nargs="?", default="paper", metavar="SCENARIO",
                        help="packaged name or .toml path (default: paper)")
    parser.add_argument("-n", type=int, default=200, help="number of runs (default 200)")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                        help="parallel processes (default: all cores)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the starts and the runs")
    parser.add_argument("--max-duration", type=positive_seconds, default=600.0, metavar="S",
                        help="give a run up after this many simulated seconds")
    parser.add_argument("--json", action="store_true",
                        help="end with the figures as one JSON object on the last line")


def run(args: argparse.Namespace) -> int:
    """Run the campaign; exit 0 when every run docked without contact, else 1; 2 on bad input."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn
    from rich.table import Table

    from hil.controllers.symbolic import SymbolicError
    from hil.runs.campaign import (
        PAPER_TANK_MINUTES,
        CampaignStats,
        campaign_specs,
        draw_starts,
        run_campaign,
    )
    from hil.runs.sim_run import SimRunSpec, synthesizer_for
    from hil.runtime.assembly import LayoutSolver, layout_from_scenario
    from hil.runtime.settings import LoopConfig
    from hil.scenarios import ScenarioError, load_scenario

    if args.n < 1 or args.workers < 1:
        print("hil campaign: -n and --workers must be at least 1", file=sys.stderr)
        return 2
    console = Console(stderr=args.json)
    try:
        scenario = load_scenario(args.scenario)
        solver = LayoutSolver(scenario, synthesizer_for(scenario))
        controller = solver(layout_from_scenario(scenario)).controller
        starts, discarded = draw_starts(controller, args.n, args.seed)
    except (ScenarioError, SymbolicError, ValueError) as err:
        print(f"hil campaign: {err}", file=sys.stderr)
        return 2
    # Static obstacles: re-synthesis on a timer would recompute the same controller.
    base = SimRunSpec(scenario=args.scenario, loop=LoopConfig(
        resynthesis_period_s=None, max_duration_s=args.max_duration))
    specs = campaign_specs(base, starts, seed0=args.seed)
    with Progress("[progress.description]{task.description}", BarColumn(), MofNCompleteColumn(),
                  TimeElapsedColumn(), console=console) as progress:
        task = progress.add_task(f"{scenario.name}: docking runs", total=len(specs))
        summaries = run_campaign(specs, args.workers,
                                 lambda _s: progress.advance(task))
    stats = CampaignStats.of(summaries)
    table = Table(title=f"campaign: {scenario.name}, {stats.runs} runs "
                        f"({discarded} non-winning starts redrawn)")
    table.add_column("measure")
    table.add_column("hil (sim)", justify="right")
    table.add_column("paper", justify="right")
    table.add_row("docked", f"{stats.docked}/{stats.runs}", "5/5 sim, 10/10 tank")
    table.add_row("runs with hull contact", str(stats.contacts), "-")
    mean, low, high = stats.docking_min
    table.add_row("docking time mean (min..max)", f"{mean:.2f} ({low:.2f}..{high:.2f}) min",
                  "{:.2f} ({:.2f}..{:.2f}) min".format(*PAPER_TANK_MINUTES))
    table.add_row("least hull clearance", f"{stats.min_clearance_m:.3f} m", "-")
    for label, value, paper in zip(("surge m/s", "sway m/s", "yaw deg/s"), stats.tracking_rms,
                                   (0.00768, 0.00431, 0.62108), strict=True):
        table.add_row(f"tracking RMS, {label}", f"{value:.5f}", f"{paper}")
    table.add_row("wall time per run", f"{stats.wall_s_mean:.2f} s", "-")
    console.print(table)
    if args.json:
        print(json.dumps({**asdict(stats), "scenario": args.scenario,
                          "discarded_starts": discarded}))
    return 0 if stats.docked == stats.runs and stats.contacts == 0 else 1
