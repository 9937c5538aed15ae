"""`hil campaign [SCENARIO] -n N [--workers K] [--moving F]`: Monte Carlo over random starts.

Draws N winning starts (a share F already moving) and seeds, runs them on local
processes (default), a local Dask cluster (``--dask``) or the Dask cluster of a
scheduler (``--scheduler tcp://HOST:PORT``), streams each finished run to a results
file as one JSON line (``--results FILE``; ``--resume FILE`` continues a stopped
campaign) and prints the report of :mod:`hil.commands.campaign_report`; `--json`
adds it, per run and in total, as one JSON object on the last line.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from hil.commands.common import non_negative_int, positive_seconds
from hil.commands.executor_cli import (
    add_executor_arguments,
    add_results_arguments,
    executor_choice,
    run_specs,
)
from hil.commands.stages import Stages

HELP = "run many simulated dockings from random starts in parallel and compare with the paper"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.add_argument("scenario", nargs="?", default="paper", metavar="SCENARIO",
                        help="packaged name or .toml path (default: paper)")
    parser.add_argument("-n", type=int, default=200, help="number of runs (default 200)")
    add_executor_arguments(parser, None)
    parser.add_argument("--seed", type=non_negative_int, default=0,
                        help="seed of the starts and the runs")
    parser.add_argument("--max-duration", type=positive_seconds, default=600.0, metavar="S",
                        help="give a run up after this many simulated seconds")
    parser.add_argument("--moving", type=float, default=0.5, metavar="FRACTION",
                        help="share of runs that start with a random body velocity, uniform "
                             "in the scenario's input box (default 0.5)")
    parser.add_argument("--select", default="J", metavar="POLICY[,POLICY...]",
                        help="which listed safe input each run flies: J (the paper's cost, "
                             "default), random, largest-change, zigzag, fastest, mixed; "
                             "comma-separated, the runs rotate through them (the guarantee "
                             "is promised for every listed input: an adversary stresses it)")
    add_results_arguments(parser)
    parser.add_argument("--json", action="store_true",
                        help="end with the figures as one JSON object on the last line")


def run(args: argparse.Namespace) -> int:
    """Run the campaign; return the exit status.

    0 every run docked without contact, 1 otherwise, 2 bad input, 130 stopped by Ctrl-C,
    3 the Dask scheduler went away (the finished runs are still reported, table and
    JSON, and kept in the results file).
    """
    Stages("hil campaign").say(f"{args.n} runs of scenario {args.scenario}: loading ...")
    from rich.console import Console

    from hil.commands.campaign_report import report
    from hil.controllers.symbolic import SymbolicError
    from hil.runs.backends import require_backend
    from hil.runs.campaign import (
        StartRegion,
        campaign_specs,
        draw_starts,
        draw_velocities,
        first_decision_s,
        sim_job,
    )
    from hil.runs.errors import ExecutorError
    from hil.runs.policies import policies_of
    from hil.runs.sim_run import SimRunSpec
    from hil.runs.stack_assembly import synthesizer_for
    from hil.runtime.assembly import LayoutSolver, layout_from_scenario
    from hil.runtime.settings import LoopConfig
    from hil.scenarios import ScenarioError, load_scenario

    if args.n < 1 or args.workers < 1:
        print("hil campaign: error: -n and --workers must be at least 1", file=sys.stderr)
        return 2
    try:
        require_backend(executor_choice(args))
        policies = policies_of(args.select)
    except (ExecutorError, ValueError) as err:
        print(f"hil campaign: error: {err}", file=sys.stderr)
        return 2
    console = Console(stderr=args.json)
    try:
        scenario = load_scenario(args.scenario)
        solver = LayoutSolver(scenario, synthesizer_for(scenario))
        controller = solver(layout_from_scenario(scenario)).controller
        velocities = draw_velocities(scenario, args.n, args.moving, args.seed)
        starts, discarded = draw_starts(
            controller, args.n, args.seed, StartRegion.of(scenario), velocities,
            settle_s=first_decision_s(LoopConfig()), scenario=scenario,
        )
    except (ScenarioError, SymbolicError, ValueError) as err:
        print(f"hil campaign: error: {err}", file=sys.stderr)
        return 2
    # Static obstacles: re-synthesis on a timer would recompute the same controller.
    base = SimRunSpec(scenario=args.scenario, loop=LoopConfig(
        resynthesis_period_s=None, max_duration_s=args.max_duration))
    specs = [replace(spec, select=policies[i % len(policies)]) for i, spec in
             enumerate(campaign_specs(base, starts, seed0=args.seed, velocities=velocities))]
    job = sim_job("campaign", [args.scenario])
    ran = run_specs(args, "campaign", f"campaign-{Path(args.scenario).stem}", specs, job,
                    console, f"{scenario.name}: docking runs")
    if isinstance(ran, int):
        return ran
    outcome, results = ran
    return report(outcome, command="campaign", console=console, as_json=args.json,
                  title=f"campaign: {scenario.name} ({discarded} non-winning starts redrawn)",
                  extra={"scenario": args.scenario, "discarded_starts": discarded,
                         "moving": args.moving},
                  results=results)
