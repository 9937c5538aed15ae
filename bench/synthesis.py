"""Benchmark of the symbolic controller: `python -m bench synthesis [--quick]`.

Prints, on the paper arena at the reference resolution (160 x 120 x 60 cells, 175
inputs, tau 2 s, the scenario's deviation budget; the game runs over (cell, reference in
force), 175 layers): abstraction time cold and cached; synthesis median over several
obstacle layouts (the paper's, then obstacles shifted at random); threads 1 vs 2; peak
memory; controller file size; safe_inputs latency; winning fraction from rest; growth
with grid size; and a dense numpy baseline on the same tables (timed for a few levels
and extrapolated to the level count), with ratios. Targets from issue 11: synthesis
<= 0.5 s on one core (goal 0.1 s), winning >= 85 % of free cells; the paper: about
0.5 s on an A6000 GPU with 400 MB (for the idealized abstraction).
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numba
import numpy as np

from bench import layout_latency
from hil.controllers.symbolic import (
    Controller,
    SymbolicProblem,
    Synthesizer,
    Tables,
    build_tables,
)
from hil.controllers.symbolic.reference import dense_fixed_point, dense_tube_free
from hil.scenarios import Scenario, load_scenario


def _layouts(scenario: Scenario, n: int, rng: np.random.Generator) -> list[SymbolicProblem]:
    out = [SymbolicProblem.from_scenario(scenario)]
    while len(out) < n:
        shift = rng.uniform(-0.3, 0.3, size=(len(scenario.obstacles), 2))
        try:
            out.append(SymbolicProblem.from_scenario(scenario.with_obstacles_moved(shift)))
        except ValueError:
            continue
    return out


def _solve_times(
    tables: Tables, layouts: list[SymbolicProblem], threads: int
) -> tuple[float, float, list[Controller]]:
    """Return the median wall time, the median CPU time (all threads) and the controllers."""
    synthesizer = Synthesizer(tables, threads=threads, memo=False, use_cache=False)
    synthesizer.solve_problem(layouts[0])  # warm-up: numba load or compile
    controllers = []
    cpu = []
    for p in layouts:
        start = time.process_time()
        controllers.append(synthesizer.solve_problem(p))
        cpu.append(time.process_time() - start)
    wall = statistics.median(c.stats.seconds for c in controllers)
    return wall, statistics.median(cpu), controllers


def _kernel_ratio(
    tables: Tables, problem: SymbolicProblem, threads: int, reps: int
) -> tuple[float, float, bool]:
    """Return the best wall times of the frontier and planes kernels, and whether they agree.

    Interleaved (frontier, planes, frontier, planes, ...) in this process, so that the
    machine's load weighs on both alike; each warmed first.
    """
    solvers = {
        kernel: Synthesizer(tables, threads=threads, memo=False, kernel=kernel)
        for kernel in ("frontier", "planes")
    }
    best = {kernel: float("inf") for kernel in solvers}
    out: dict[str, Controller] = {}
    for kernel, synthesizer in solvers.items():
        out[kernel] = synthesizer.solve_problem(problem)  # warm-up: numba load or compile
    for _ in range(reps):
        for kernel, synthesizer in solvers.items():
            start = time.perf_counter()
            out[kernel] = synthesizer.solve_problem(problem)
            best[kernel] = min(best[kernel], time.perf_counter() - start)
    old, new = out["frontier"], out["planes"]
    same = bool(np.array_equal(old.values, new.values) and old.stats.levels == new.stats.levels)
    return best["frontier"], best["planes"], same


def _vs(target_s: float, measured_s: float) -> str:
    verdict = "meets" if measured_s <= target_s else "misses"
    return f"{verdict} {target_s * 1e3:.0f} ms ({target_s / measured_s:.2f}x)"


def _row(name: str, value: str, note: str = "") -> None:
    print(f"  {name:<38} {value:>14}  {note}")


def _scaled(scenario: Scenario, cell_m: float, heading_cells: int) -> Scenario:
    return replace(scenario, cell_m=(cell_m, cell_m), heading_cells=heading_cells)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; return 0."""
    parser = argparse.ArgumentParser(prog="python -m bench synthesis", description=__doc__)
    parser.add_argument(
        "--layouts", type=int, default=9, help="obstacle layouts (first: the paper's)"
    )
    parser.add_argument("--dense-sweeps", type=int, default=2, help="dense baseline sweeps to time")
    parser.add_argument(
        "--kernel-reps", type=int, default=3, help="interleaved solves per kernel (best of)"
    )
    parser.add_argument(
        "--quick", action="store_true", help="fewer layouts, no scaling, no dense baseline"
    )
    parser.add_argument(
        "--latency-only", action="store_true",
        help="only the time from a new layout to a controller at the vessel (bench latency)",
    )
    args = parser.parse_args(argv)
    layout_latency.run(quick=args.quick)
    if args.latency_only:
        return 0
    n_layouts = 3 if args.quick else args.layouts
    rng = np.random.default_rng(2025)
    scenario = load_scenario("paper")
    problem = SymbolicProblem.from_scenario(scenario)
    g = problem.grid
    max_threads = int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
    print(
        f"symbolic synthesis benchmark: paper arena {g.nx} x {g.ny} x {g.npsi} = {g.n_cells} "
        f"cells, {problem.inputs.shape[0]} inputs, tau {problem.tau_s} s, "
        f"numba {numba.__version__}, {max_threads} threads max"
    )

    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp)
        start = time.perf_counter()
        tables = build_tables(g, problem.inputs, problem.tau_s, problem.budget, problem.late_s)
        cold = time.perf_counter() - start
        problem.tables(cache_dir=cache)
        start = time.perf_counter()
        tables, cached = problem.tables(cache_dir=cache)
        warm = time.perf_counter() - start
        assert cached

        layouts = _layouts(scenario, n_layouts, rng)
        t2, c2, controllers = _solve_times(tables, layouts, threads=2)
        t1, c1, _ = _solve_times(tables, layouts, threads=1)
        paper = controllers[0]
        traced = Synthesizer(tables, trace_memory=True, use_cache=False).solve_problem(problem)
        path = cache / "paper.npz"
        paper.save(path)
        size_mb = path.stat().st_size / 2**20

    winning = list(np.argwhere(paper.values > 0))
    picks = rng.choice(len(winning), 2000)
    states = []
    for idx in picks:
        lo, hi = g.cell_bounds(*(int(v) for v in winning[idx]))
        states.append(lo + rng.random(3) * (hi - lo))
    for s in states[:50]:
        paper.safe_inputs(s)
    start = time.perf_counter()
    counts = [len(paper.safe_inputs(s)) for s in states]
    lookup_us = (time.perf_counter() - start) / len(states) * 1e6
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

    print("\nreference resolution")
    _row("abstraction, cold (build tables)", f"{cold:.3f} s", "target <= 2 s")
    _row(
        "abstraction, cached (load)", f"{warm * 1e3:.1f} ms", f"{cold / warm:.0f}x faster than cold"
    )
    _row(
        f"synthesis median, {len(layouts)} layouts, 2 threads",
        f"{t2 * 1e3:.1f} ms",
        f"{_vs(0.5, t2)}, goal {_vs(0.1, t2)}; CPU {c2 * 1e3:.0f} ms (both threads)",
    )
    _row(
        "synthesis median, 1 thread",
        f"{t1 * 1e3:.1f} ms",
        f"{_vs(0.5, t1)}, goal {_vs(0.1, t1)}; CPU {c1 * 1e3:.0f} ms; 2 threads {t1 / t2:.2f}x",
    )
    _row("machine load (1 min average)", f"{os.getloadavg()[0]:.1f}", "on 2 cores: timings inflate")
    _row("iterations (paper layout)", f"{paper.stats.levels}", "")
    _row(
        "peak memory during synthesis (traced)",
        f"{traced.stats.peak_bytes / 2**20:.1f} MB",
        "paper 400 MB GPU + 500 MB host (one layer)",
    )
    _row("process max RSS (incl. numba, numpy)", f"{rss_mb:.0f} MB", "")
    _row("controller file", f"{size_mb:.2f} MB", "175 layers of winning bits and values")
    _row(
        "safe_inputs per state",
        f"{lookup_us:.1f} us",
        f"target <= 100 us; mean {np.mean(counts):.1f} inputs",
    )
    _row(
        "winning fraction of free cells, from rest",
        f"{100 * paper.stats.winning_fraction:.2f} %",
        "target >= 85 %",
    )
    fractions = [c.stats.winning_fraction for c in controllers]
    _row("winning fraction, min over layouts", f"{100 * min(fractions):.2f} %", "")
    best = min(t1, t2)
    _row(
        "paper (0.5 s, A6000 GPU) / ours",
        f"{0.5 / best:.2f}x",
        "best of 1 and 2 threads, 2 CPU cores",
    )

    print(
        "\nkernels on the paper layout: frontier (sweep.py, the reference) vs bit planes "
        "(planes_kernel.py, the default), interleaved in this process, best of "
        f"{1 if args.quick else args.kernel_reps}"
    )
    for threads in (1, 2):
        old_s, new_s, same = _kernel_ratio(
            tables, problem, threads, 1 if args.quick else args.kernel_reps
        )
        _row(
            f"frontier / planes kernel, {threads} thread{'s' if threads > 1 else ''}",
            f"{old_s:.2f} / {new_s:.2f} s",
            f"planes {new_s / old_s:.2f}x the frontier's; same values: {same}",
        )

    if args.quick:
        return 0

    print("\ngrowth with grid size (paper layout, median of 3; wall ms for 1 and 2 threads)")
    print(
        f"  {'grid':<18} {'cells':>9} {'tables s':>9} {'1 thr ms':>9} {'2 thr ms':>9} "
        f"{'iter':>5} {'ns/cell':>8}"
    )
    for cell_m, heading_cells in ((0.1, 30), (0.08, 45), (0.05, 60), (0.04, 72)):
        sc = _scaled(scenario, cell_m, heading_cells)
        p = SymbolicProblem.from_scenario(sc)
        start = time.perf_counter()
        tb = build_tables(p.grid, p.inputs, p.tau_s, p.budget, p.late_s)
        tb_s = time.perf_counter() - start
        one, _, cs = _solve_times(tb, [p, p, p], threads=1)
        two, _, _ = _solve_times(tb, [p, p, p], threads=2)
        ns_per_cell = min(one, two) / p.grid.n_cells * 1e9
        print(
            f"  {p.grid.nx:>4} x {p.grid.ny:>3} x {p.grid.npsi:>3}   {p.grid.n_cells:>9} "
            f"{tb_s:>9.3f} {one * 1e3:>9.1f} {two * 1e3:>9.1f} {cs[0].stats.levels:>5} "
            f"{ns_per_cell:>8.1f}"
        )

    print(
        "\ndense numpy baseline (same tables and masks, every state and input per level, "
        f"{args.dense_sweeps} levels timed)"
    )
    flat = tables.hull_psi.reshape(-1, 2)
    free = problem.free_masks(flat[:, 0], flat[:, 1])
    target = problem.target_cells()
    start = time.perf_counter()
    tube = dense_tube_free(tables, free)
    tube_s = time.perf_counter() - start
    start = time.perf_counter()
    values, done = dense_fixed_point(tables, free, target, args.dense_sweeps, tube)
    sweep_s = (time.perf_counter() - start) / max(done, 1)
    total = tube_s + sweep_s * (paper.stats.levels + 1)
    rest = paper.rest_index
    fast = paper.layer_values(rest)
    agree = np.array_equal(values[rest], np.where(fast <= done, fast, -1))
    _row("dense tube precompute", f"{tube_s:.2f} s", "")
    _row("dense level", f"{sweep_s:.2f} s", f"first {done} levels agree with fast: {agree}")
    _row(
        f"dense total ({paper.stats.levels + 1} levels, extrapolated)",
        f"{total:.1f} s",
        f"fast solver is {total / best:.0f}x faster",
    )
    return 0
