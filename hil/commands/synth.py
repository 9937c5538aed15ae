"""`hil synth SCENARIO [--json] [--save FILE]`: synthesize the symbolic controller.

Prints the grid, the abstraction and synthesis times, the fixed-point iterations, the
winning fraction of the free cells and the memory; with `--json` the same figures
follow as one JSON object on the last line. A layout solved before is read from the
solved-controller store (the report says so); `--no-cache` bypasses every cache (tables,
stored controllers, the process's memo). It solves once; `--repeat N` solves N times more
without any cache and adds their median. It says each stage on stderr as it starts
(tables, kernels, synthesis, from cache or solved) and the true total at the end. With
`--start X,Y,PSI_DEG` also the time until a controller covers that state at rest (the
solve's early stop, `start_seconds`) beside the full solve's, always solved.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hil.commands.common import start_pose
from hil.commands.stages import Stages

if TYPE_CHECKING:
    from hil.controllers.symbolic import Controller, SymbolicProblem, Synthesizer
    from hil.scenarios import Scenario

HELP = "synthesize the symbolic docking controller for a scenario and report its figures"

_PROG = "hil synth"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.add_argument(
        "scenario", metavar="SCENARIO", help="packaged name (paper, coarse) or a .toml path"
    )
    parser.add_argument(
        "--json", action="store_true", help="end with one JSON object on the last line"
    )
    parser.add_argument("--save", metavar="FILE", type=Path, help="write the controller (.npz)")
    parser.add_argument(
        "--threads", type=int, default=1, help="kernel threads (default 1; 0 for all cores)"
    )
    parser.add_argument(
        "--cache-dir", type=Path, default=None, help="table and solved-controller cache folder"
    )
    parser.add_argument(
        "--no-cache",
        action="store_true",
        help="neither read nor write any cache (tables, solved controllers): every run solves",
    )
    parser.add_argument(
        "--repeat",
        type=_repeat_count,
        default=1,
        metavar="N",
        help="solve N times: the first as always (tables, store), N - 1 more without any "
        "cache, their median reported beside (default 1: solve once, or read the store)",
    )
    parser.add_argument(
        "--start",
        type=start_pose,
        default=None,
        metavar="X,Y,PSI_DEG",
        help="also time a solve until a controller covers this state at rest (m, m, deg)",
    )


def _repeat_count(text: str) -> int:
    """Parse ``--repeat N``: a whole number of solves, at least 1."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"needs a whole number of solves >= 1, got {text!r}")
    return value


@dataclass(frozen=True)
class _Solved:
    """What the synthesis stage produced (figures in s)."""

    problem: SymbolicProblem
    tables_nbytes: int
    abstraction_s: float
    abstraction_cached: bool
    first: Controller
    first_s: float
    repeats_s: tuple[float, ...]
    start_figures: dict[str, Any] | None


def _synthesize(args: argparse.Namespace, scenario: Scenario, stages: Stages) -> _Solved:
    """Build or load the tables, solve (or read the stored controller), repeat if asked.

    Raises:
        ScenarioError: The start lies outside the grid.
        SymbolicError: The synthesis refused the problem.
    """
    from hil.controllers.symbolic import SymbolicProblem, Synthesizer
    from hil.core.jit import kernels_cached
    from hil.scenarios import ScenarioError

    problem = SymbolicProblem.from_scenario(scenario)
    if args.start is not None and problem.grid.cell_of(args.start) is None:
        raise ScenarioError(f"--start {_pose_text(args.start)} lies outside the grid")
    start = time.perf_counter()
    with stages.stage("loading the abstraction tables (built and cached when missing)"):
        tables, cached = problem.tables(cache_dir=args.cache_dir, use_cache=not args.no_cache)
    abstraction_s = time.perf_counter() - start
    stages.say(f"tables {'read from cache' if cached else 'built'} in {abstraction_s:.2f} s")
    threads = args.threads if args.threads > 0 else None
    synthesizer = Synthesizer(
        tables, threads=threads, trace_memory=True, memo=not args.no_cache,
        use_cache=not args.no_cache, cache_dir=args.cache_dir,
    )  # fmt: skip
    kernels = (
        "the compiled kernels from numba's cache"
        if kernels_cached()
        else "no compiled kernels yet (numba's cache is cold: a solve compiles them first, "
        "about a minute)"
    )
    start = time.perf_counter()
    with stages.stage(
        f"synthesizing on {problem.grid.n_cells} cells, or reading the solved-controller "
        f"store; {kernels}"
    ):
        first = synthesizer.solve_problem(problem)
    first_s = time.perf_counter() - start
    if first.stats.loaded:
        stages.say(f"controller read from the solved-controller store in {first_s:.2f} s")
    else:
        stages.say(f"solved in {first_s:.2f} s ({first.stats.levels} iterations)")
    repeats: list[float] = []
    if args.repeat > 1:
        again = Synthesizer(tables, threads=threads, memo=False, use_cache=False)
        for n in range(args.repeat - 1):
            with stages.stage(f"solving again without caches ({n + 1} of {args.repeat - 1})"):
                repeats.append(again.solve_problem(problem).stats.seconds)
    synthesizer.wait_stored()
    start_figures = None
    if args.start is not None:
        with stages.stage(f"solving once more, watching the start {_pose_text(args.start)}"):
            start_figures = _start_figures(
                Synthesizer(tables, threads=threads, memo=False, use_cache=False),
                problem,
                args.start,
            )
    return _Solved(
        problem,
        tables.nbytes(),
        abstraction_s,
        cached,
        first,
        first_s,
        tuple(repeats),
        start_figures,
    )


def run(args: argparse.Namespace) -> int:
    """Synthesize, print the report; return 0, 1 without a winning start, 2 on bad input."""
    stages = Stages(_PROG)
    stages.say(f"scenario {args.scenario}: loading (numpy, numba)")
    from hil.controllers.symbolic import SymbolicError
    from hil.scenarios import ScenarioError, load_scenario

    try:
        scenario = load_scenario(args.scenario)
        solved = _synthesize(args, scenario, stages)
    except (ScenarioError, SymbolicError) as err:
        return _error(str(err))
    except MemoryError as err:
        return _error(
            f"not enough memory to synthesize on the scenario's grid of {args.scenario!r} "
            f"({err}): use a coarser [grid] cell_m or fewer heading_cells"
        )
    if args.save is not None:
        with stages.stage(f"saving {args.save}"):
            solved.first.save(args.save)
    with stages.stage("counting the winning, first-decision and safety cells"):
        summary = _summary(args, scenario, solved)
    status = _report(args, scenario, solved, summary)
    stages.say(f"done in {stages.total_s():.1f} s")
    if args.json:
        print(json.dumps(summary))
    return status


def _error(message: str) -> int:
    print(f"{_PROG}: error: {message}", file=sys.stderr)
    return 2


def _summary(args: argparse.Namespace, scenario: Scenario, solved: _Solved) -> dict[str, Any]:
    """Return the report as the JSON object of `--json`."""
    import numpy as np

    problem, controller = solved.problem, solved.first
    stats = controller.stats
    grid = problem.grid
    first_cells = int(np.count_nonzero(controller.first_decision_winning()))
    safe_cells, waiting_cells = controller.safe_counts()
    summary: dict[str, Any] = {
        "scenario": scenario.name,
        "grid": list(grid.shape),
        "grid_cells": grid.n_cells,
        "inputs": int(problem.inputs.shape[0]),
        "tau_s": problem.tau_s,
        "budget": problem.budget.source or "zero (the paper's ideal loop)",
        "abstraction_seconds": solved.abstraction_s,
        "abstraction_cached": solved.abstraction_cached,
        "first_synthesis_seconds": solved.first_s,
        "controller_cached": stats.loaded,
        "synthesis_seconds": stats.seconds,
        "synthesis_runs": 1 + len(solved.repeats_s),
        "repeat_seconds": list(solved.repeats_s),
        "repeat_median_seconds": (float(np.median(solved.repeats_s)) if solved.repeats_s else None),
        "iterations": stats.levels,
        "threads": stats.threads,
        "free_cells": stats.free_cells,
        "winning_cells": stats.winning_cells,
        "target_cells": stats.target_cells,
        "winning_fraction": stats.winning_fraction,
        "first_decision_cells": first_cells,
        "first_decision_fraction": first_cells / stats.free_cells if stats.free_cells else 0.0,
        "safe_cells": safe_cells,
        "safe_not_winning_cells": waiting_cells,
        "peak_memory_mb": stats.peak_bytes / 2**20,
        "tables_mb": solved.tables_nbytes / 2**20,
    }
    if solved.start_figures is not None:
        summary.update(solved.start_figures)
    if args.save is not None:
        summary["controller_file"] = str(args.save)
        summary["controller_file_mb"] = args.save.stat().st_size / 2**20
    return summary


def _synthesis_text(solved: _Solved) -> str:
    """Return the report's synthesis line: one figure, and the repeats' median if any."""
    import numpy as np

    stats = solved.first.stats
    if stats.loaded:
        text = (
            f"synthesis    read from the solved-controller store in {solved.first_s:.3f} s "
            f"(it took {stats.seconds:.3f} s to solve; --no-cache to solve), "
            f"{stats.levels} iterations"
        )
    else:
        text = (
            f"synthesis    {stats.seconds:.3f} s, {stats.levels} iterations, "
            f"{stats.threads} thread(s)"
        )
    if solved.repeats_s:
        text += (
            f"; solved {len(solved.repeats_s)} more time(s) without caches: median "
            f"{float(np.median(solved.repeats_s)):.3f} s"
        )
    return text


def _report(
    args: argparse.Namespace, scenario: Scenario, solved: _Solved, summary: dict[str, Any]
) -> int:
    """Print the report (`summary` from :func:`_summary`); return 1 when no start can dock."""
    grid, controller = solved.problem.grid, solved.first
    stats = controller.stats
    print(f"scenario     {scenario.name}: {scenario.description}")
    print(
        f"grid         {grid.nx} x {grid.ny} x {grid.npsi} = {grid.n_cells} cells, "
        f"{summary['inputs']} inputs, tau {solved.problem.tau_s} s"
    )
    print(
        f"abstraction  {solved.abstraction_s:.3f} s "
        f"({'from cache' if solved.abstraction_cached else 'built'})"
    )
    print(_synthesis_text(solved))
    first_cells = summary["first_decision_cells"]
    print(
        f"winning      {stats.winning_cells} of {stats.free_cells} free cells "
        f"({100 * stats.winning_fraction:.2f} %) with the rest reference held; a first "
        f"decision at rest (a start: what `hil campaign` draws) finds a safe input in "
        f"{first_cells} ({100 * summary['first_decision_fraction']:.2f} %)"
    )
    print(
        f"safety       {summary['safe_cells']} cells where the vessel can stay safe from rest "
        f"for ever (the safety controller's set); {summary['safe_not_winning_cells']} of them "
        "do not win for docking: there it waits until docking wins"
    )
    solved_here = "" if not stats.loaded else " (not solved here)"
    print(
        f"memory       {summary['peak_memory_mb']:.1f} MB peak during synthesis{solved_here}, "
        f"tables {summary['tables_mb']:.1f} MB"
    )
    if solved.start_figures is not None:
        print(_start_text(solved.start_figures))
    if args.save is not None:
        print(f"saved        {args.save} ({summary['controller_file_mb']:.2f} MB)")
    if not controller.has_winning_start:
        print(
            "no winning cell outside the target: no start can be guaranteed to dock",
            file=sys.stderr,
        )
        return 1
    return 0


def _start_figures(
    synthesizer: Synthesizer, problem: SymbolicProblem, start: tuple[float, float, float]
) -> dict[str, Any]:
    """Solve once more, watching `start` at rest: when a controller covers it, and the end.

    Raises:
        ScenarioError: The start lies outside the grid.
    """
    import numpy as np

    from hil.controllers.symbolic import Watch
    from hil.scenarios import ScenarioError

    cell = problem.grid.cell_of(start)
    if cell is None:
        raise ScenarioError(f"--start {_pose_text(start)} lies outside the grid")
    rest = synthesizer.lattice.nearest(np.zeros(3))
    stages = list(synthesizer.solve_stages(problem, Watch(cell, rest)))
    early = stages[0] if len(stages) > 1 else None
    full = stages[-1]
    value = full.cell_value(cell, rest)
    covered_at = early if early is not None else (full if value >= 0 else None)
    return {
        "start": list(start),
        "start_cell": list(cell),
        "start_value": value if value >= 0 else None,
        "start_seconds": None if covered_at is None else covered_at.stats.seconds,
        "start_levels": None if covered_at is None else covered_at.stats.levels,
        "start_full_seconds": full.stats.seconds,
    }


def _pose_text(start: Sequence[float]) -> str:
    return f"{start[0]:g},{start[1]:g},{math.degrees(start[2]):g}"


def _start_text(figures: dict[str, Any]) -> str:
    where = _pose_text(figures["start"])
    if figures["start_seconds"] is None:
        return (
            f"start        {where}: not winning at rest in this layout "
            f"(full solve {figures['start_full_seconds']:.3f} s)"
        )
    return (
        f"start        {where}: value {figures['start_value']}, covered after "
        f"{figures['start_seconds']:.3f} s ({figures['start_levels']} levels), full solve "
        f"{figures['start_full_seconds']:.3f} s"
    )
