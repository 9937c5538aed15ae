"""`hil campaign [SCENARIO] -n N [--workers K] [--moving F]`: Monte Carlo over random starts.

Prints the success rate, the docking-time distribution beside the paper's tank
figures, the least hull clearance, the tracking error and the guarantee's
violations on the true state (tube exits, successor misses, value not decreasing,
centre in an inflated obstacle, hull contact or outside the arena, and the broken
premises: late intervals, estimation), for all runs, those started at rest and
those started moving; `--json` adds them, per run and in total, as one JSON
object on the last line.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from dataclasses import asdict
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.table import Table

    from hil.runs.campaign import CampaignRun

from hil.commands.common import EXIT_STOPPED, positive_seconds

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
    parser.add_argument("--moving", type=float, default=0.5, metavar="FRACTION",
                        help="share of runs that start with a random body velocity, uniform "
                             "in the scenario's input box (default 0.5)")
    parser.add_argument("--json", action="store_true",
                        help="end with the figures as one JSON object on the last line")


def _guarantee_rows(table: Table, groups: list[list[CampaignRun]]) -> None:
    """Add the guarantee's rows: intervals with a violation (worst size) per group."""
    from hil.runs.guarantee import GuaranteeViolations

    totals = [GuaranteeViolations.total(g for _, g in runs) for runs in groups]
    rows = (
        ("tube exits (worst m)", "tube_exits", "worst_tube_exit_m", "{:.3f}"),
        ("successor misses (worst m)", "successor_misses", "worst_successor_miss_m", "{:.3f}"),
        ("  heading misses at tau (worst deg)", None, "worst_heading_miss_rad", "deg"),
        ("value not decreasing", "value_not_decreasing", None, ""),
        ("centre in inflated obstacle (depth m)", "inflated_obstacle",
         "worst_inflated_depth_m", "{:.3f}"),
        ("hull contact (penetration m)", "hull_contacts", "worst_hull_penetration_m", "{:.3f}"),
        ("hull outside arena (worst m)", "hull_outside_arena", "worst_hull_outside_m", "{:.3f}"),
        ("late intervals (worst s)", "late_intervals", "worst_late_s", "{:.2f}"),
        ("estimate in another cell (worst m)", "estimation_misses", "worst_estimation_m",
         "{:.4f}"),
    )
    table.add_row("judged intervals", *(f"{t.intervals}" for t in totals), "-")
    for label, count, worst, fmt in rows:
        cells = []
        for t in totals:
            size = "" if worst is None else getattr(t, worst)
            if fmt == "deg":
                cells.append(f"{math.degrees(float(size)):.1f}")
                continue
            text = str(getattr(t, count)) if count is not None else ""
            if worst is not None:
                text += f" ({fmt.format(size)})"
            cells.append(text)
        table.add_row(label, *cells, "-")
    table.add_row("runs with a violation",
                  *(str(sum(g.violations > 0 for _, g in runs)) for runs in groups), "-")


def run(args: argparse.Namespace) -> int:
    """Run the campaign; return the exit status.

    0 every run docked without contact, 1 otherwise, 2 bad input, 130 stopped by Ctrl-C
    (the finished runs are still reported, table and JSON).
    """
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn
    from rich.table import Table

    from hil.controllers.symbolic import SymbolicError
    from hil.runs.campaign import (
        PAPER_TANK_MINUTES,
        CampaignStats,
        StartRegion,
        campaign_specs,
        draw_starts,
        draw_velocities,
        run_campaign,
    )
    from hil.runs.guarantee import GuaranteeViolations
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
        velocities = draw_velocities(scenario, args.n, args.moving, args.seed)
        starts, discarded = draw_starts(
            controller, args.n, args.seed, StartRegion.of(scenario), velocities
        )
    except (ScenarioError, SymbolicError, ValueError) as err:
        print(f"hil campaign: {err}", file=sys.stderr)
        return 2
    # Static obstacles: re-synthesis on a timer would recompute the same controller.
    base = SimRunSpec(scenario=args.scenario, loop=LoopConfig(
        resynthesis_period_s=None, max_duration_s=args.max_duration))
    specs = campaign_specs(base, starts, seed0=args.seed, velocities=velocities)
    with Progress("[progress.description]{task.description}", BarColumn(), MofNCompleteColumn(),
                  TimeElapsedColumn(), console=console) as progress:
        task = progress.add_task(f"{scenario.name}: docking runs", total=len(specs))
        outcome = run_campaign(specs, args.workers, lambda _r: progress.advance(task))
    results, specs = outcome.runs, outcome.specs
    if not results:
        print("hil campaign: stopped before any run finished", file=sys.stderr)
        return EXIT_STOPPED
    groups = [results,
              [r for r, s in zip(results, specs, strict=True) if s.start_velocity is None],
              [r for r, s in zip(results, specs, strict=True) if s.start_velocity is not None]]
    all_stats = [CampaignStats.of([summary for summary, _ in g]) for g in groups]
    stats = all_stats[0]
    stopped = (f", STOPPED after {len(results)} of {outcome.planned} runs"
               if outcome.stopped else "")
    table = Table(title=f"campaign: {scenario.name}, {stats.runs} runs "
                        f"({discarded} non-winning starts redrawn){stopped}")
    table.add_column("measure")
    for name in ("all", "at rest", "moving"):
        table.add_column(f"hil (sim), {name}", justify="right")
    table.add_column("paper", justify="right")
    table.add_row("docked, of the runs winning at their first decision",
                  *(f"{s.docked}/{s.winning_starts}" for s in all_stats), "5/5 sim, 10/10 tank")
    table.add_row("first decision not winning (drifted while the observer settled)",
                  *(str(s.lost_at_start) for s in all_stats), "-")
    table.add_row("runs with hull contact", *(str(s.contacts) for s in all_stats), "-")
    table.add_row("docking time mean (min..max)",
                  *("{:.2f} ({:.2f}..{:.2f}) min".format(*s.docking_min) for s in all_stats),
                  "{:.2f} ({:.2f}..{:.2f}) min".format(*PAPER_TANK_MINUTES))
    table.add_row("least hull clearance", *(f"{s.min_clearance_m:.3f} m" for s in all_stats), "-")
    for axis, (label, paper) in enumerate(zip(("surge m/s", "sway m/s", "yaw deg/s"),
                                              (0.00768, 0.00431, 0.62108), strict=True)):
        table.add_row(f"tracking RMS, {label}",
                      *(f"{s.tracking_rms[axis]:.5f}" for s in all_stats), f"{paper}")
    _guarantee_rows(table, groups)
    table.add_row("wall time per run", *(f"{s.wall_s_mean:.2f} s" for s in all_stats), "-")
    console.print(table)
    if args.json:
        total = GuaranteeViolations.total(g for _, g in results)
        runs = [{"seed": spec.seed, "start": list(spec.start or ()),
                 "start_velocity": None if spec.start_velocity is None
                 else list(spec.start_velocity),
                 "docked": summary.docked, "docking_time_s": summary.docking_time_s,
                 "guarantee": asdict(g)}
                for spec, (summary, g) in zip(specs, results, strict=True)]
        print(json.dumps({**asdict(stats), "scenario": args.scenario,
                          "discarded_starts": discarded, "moving": args.moving,
                          "at_rest": asdict(all_stats[1]), "moving_starts": asdict(all_stats[2]),
                          "guarantee": asdict(total),
                          "guarantee_at_rest": asdict(
                              GuaranteeViolations.total(g for _, g in groups[1])),
                          "guarantee_moving": asdict(
                              GuaranteeViolations.total(g for _, g in groups[2])),
                          "runs_with_violations": sum(g.violations > 0 for _, g in results),
                          "planned_runs": outcome.planned, "stopped": outcome.stopped,
                          "per_run": runs}))
    if outcome.stopped:
        print(f"hil campaign: stopped after {len(results)} of {outcome.planned} runs; the "
              "figures above are the finished runs", file=sys.stderr)
        return EXIT_STOPPED
    violations = GuaranteeViolations.total(g for _, g in results).violations
    return (0 if stats.docked == stats.winning_starts and stats.contacts == 0 and violations == 0
            else 1)
