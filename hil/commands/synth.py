"""`hil synth SCENARIO [--json] [--save FILE]`: synthesize the symbolic controller.

Prints the grid, the abstraction and synthesis times, the fixed-point iterations, the
winning fraction of the free cells and the memory; with `--json` the same figures
follow as one JSON object on the last line. A layout solved before is read from the
solved-controller store (the report says so); `--no-cache` bypasses every cache (tables,
stored controllers, the process's memo), so that `--repeat` times solves. With
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
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hil.commands.common import start_pose

if TYPE_CHECKING:
    from hil.controllers.symbolic import SymbolicProblem, Synthesizer

HELP = "synthesize the symbolic docking controller for a scenario and report its figures"


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
        "--repeat", type=int, default=3, help="synthesis runs; the median is reported"
    )
    parser.add_argument(
        "--start", type=start_pose, default=None, metavar="X,Y,PSI_DEG",
        help="also time a solve until a controller covers this state at rest (m, m, deg)",
    )


def run(args: argparse.Namespace) -> int:
    """Synthesize, print the report; return 0, 1 without a winning start, 2 on bad input."""
    import numpy as np

    from hil.controllers.symbolic import SymbolicError, SymbolicProblem, Synthesizer
    from hil.scenarios import ScenarioError, load_scenario

    grid_text = "scenario's"
    try:
        scenario = load_scenario(args.scenario)
        problem = SymbolicProblem.from_scenario(scenario)
        grid_text = " x ".join(str(n) for n in problem.grid.shape)
        if args.start is not None and problem.grid.cell_of(args.start) is None:
            raise ScenarioError(f"--start {_pose_text(args.start)} lies outside the grid")
        start = time.perf_counter()
        tables, cached = problem.tables(cache_dir=args.cache_dir, use_cache=not args.no_cache)
        abstraction_s = time.perf_counter() - start
        threads = args.threads if args.threads > 0 else None
        synthesizer = Synthesizer(
            tables, threads=threads, trace_memory=True, memo=not args.no_cache,
            use_cache=not args.no_cache, cache_dir=args.cache_dir,
        )  # fmt: skip
        start = time.perf_counter()
        first = synthesizer.solve_problem(problem)  # includes numba's load or compile
        first_s = time.perf_counter() - start
        runs = [first] + [
            synthesizer.solve_problem(problem) for _ in range(max(args.repeat, 1) - 1)
        ]
        synthesizer.wait_stored()
        start_figures = None if args.start is None else _start_figures(
            Synthesizer(tables, threads=threads, memo=False, use_cache=False), problem,
            args.start)
    except (ScenarioError, SymbolicError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except MemoryError as err:
        print(
            f"error: not enough memory to synthesize on the {grid_text} grid of "
            f"{args.scenario!r} ({err}): use a coarser [grid] cell_m or fewer "
            "heading_cells",
            file=sys.stderr,
        )
        return 2
    controller = runs[-1]
    stats = controller.stats
    seconds = float(np.median([c.stats.seconds for c in runs[1:] or runs]))
    # The first run also loads numba's compiled kernels; later runs show synthesis alone.
    peak_mb = max(c.stats.peak_bytes for c in runs[1:] or runs) / 2**20
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
        "abstraction_seconds": abstraction_s,
        "abstraction_cached": cached,
        "first_synthesis_seconds": first_s,
        "controller_cached": first.stats.loaded,
        "synthesis_seconds": seconds,
        "synthesis_runs": len(runs),
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
        "peak_memory_mb": peak_mb,
        "tables_mb": tables.nbytes() / 2**20,
    }
    if start_figures is not None:
        summary.update(start_figures)
    if args.save is not None:
        controller.save(args.save)
        summary["controller_file"] = str(args.save)
        summary["controller_file_mb"] = args.save.stat().st_size / 2**20

    print(f"scenario     {scenario.name}: {scenario.description}")
    print(
        f"grid         {grid.nx} x {grid.ny} x {grid.npsi} = {grid.n_cells} cells, "
        f"{summary['inputs']} inputs, tau {problem.tau_s} s"
    )
    print(f"abstraction  {abstraction_s:.3f} s ({'from cache' if cached else 'built'})")
    if first.stats.loaded:
        print(
            f"synthesis    {seconds:.3f} s when stored, read from the controller cache in "
            f"{first_s:.3f} s (--no-cache to solve), {stats.levels} iterations"
        )
    else:
        print(
            f"synthesis    {seconds:.3f} s median of {len(runs) - 1 or 1} (first run "
            f"{first_s:.3f} s), {stats.levels} iterations, {stats.threads} thread(s)"
        )
    print(
        f"winning      {stats.winning_cells} of {stats.free_cells} free cells "
        f"({100 * stats.winning_fraction:.2f} %) with the rest reference held; a first "
        f"decision at rest (a start: what `hil campaign` draws) finds a safe input in "
        f"{first_cells} ({100 * summary['first_decision_fraction']:.2f} %)"
    )
    print(
        f"safety       {safe_cells} cells where the vessel can stay safe from rest for ever "
        f"(the safety controller's set); {waiting_cells} of them do not win for docking: "
        "there it waits until docking wins"
    )
    solved_here = "" if not first.stats.loaded else " (not solved here)"
    print(
        f"memory       {peak_mb:.1f} MB peak during synthesis{solved_here}, "
        f"tables {summary['tables_mb']:.1f} MB"
    )
    if start_figures is not None:
        print(_start_text(start_figures))
    if args.save is not None:
        print(f"saved        {args.save} ({summary['controller_file_mb']:.2f} MB)")
    status = 0
    if not controller.has_winning_start:
        print(
            "no winning cell outside the target: no start can be guaranteed to dock",
            file=sys.stderr,
        )
        status = 1
    if args.json:
        print(json.dumps(summary))
    return status


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
        return (f"start        {where}: not winning at rest in this layout "
                f"(full solve {figures['start_full_seconds']:.3f} s)")
    return (
        f"start        {where}: value {figures['start_value']}, covered after "
        f"{figures['start_seconds']:.3f} s ({figures['start_levels']} levels), full solve "
        f"{figures['start_full_seconds']:.3f} s"
    )
