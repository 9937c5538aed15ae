"""`hil synth SCENARIO [--json] [--save FILE]`: synthesize the symbolic controller.

Prints the grid, the abstraction and synthesis times, the fixed-point iterations, the
winning fraction of the free cells and the memory; with `--json` the same figures
follow as one JSON object on the last line. A layout solved before is read from the
solved-controller store (the report says so); `--no-cache` bypasses every cache (tables,
stored controllers, the process's memo), so that `--repeat` times solves.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

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
        "peak_memory_mb": peak_mb,
        "tables_mb": tables.nbytes() / 2**20,
    }
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
        f"({100 * stats.winning_fraction:.2f} %)"
    )
    solved_here = "" if not first.stats.loaded else " (not solved here)"
    print(
        f"memory       {peak_mb:.1f} MB peak during synthesis{solved_here}, "
        f"tables {summary['tables_mb']:.1f} MB"
    )
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
