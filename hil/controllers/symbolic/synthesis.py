"""Reach-avoid synthesis on the cached tables: one call per obstacle layout.

Fixed point (SCOTS v0.2 `ReachabilityGame`, with values): V = 0 on the target; a cell
joins at level L + 1 if some input has an obstacle-free swept tube and all successors
with V <= L. The kernels (see :mod:`sweep`) sweep only rows near the last frontier,
64 cells per machine word, and release the GIL, so the runtime can re-synthesize in a
background thread while its loop runs (on a 2-core machine, `threads=1` there leaves a
core to the loop; numba's omp layer allows concurrent calls from several threads).
"""

from __future__ import annotations

import threading
import time
import tracemalloc
from collections.abc import Sequence
from pathlib import Path

import numba
import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.abstraction import Tables, tables_for
from hil.controllers.symbolic.controller import Controller, SynthesisStats
from hil.controllers.symbolic.errors import GridError, NoWinningSetError
from hil.controllers.symbolic.grid import obstacle_mask, target_mask
from hil.controllers.symbolic.kernels import pack_rows
from hil.controllers.symbolic.problem import SymbolicProblem
from hil.controllers.symbolic.sweep import (
    fixed_point_parallel,
    fixed_point_serial,
    init_bits,
    viable_bits,
)
from hil.core.shapes import Shape

BoolArray = NDArray[np.bool_]
I32Array = NDArray[np.int32]

__all__ = ["Synthesizer", "synthesize"]

_TRACE_LOCK = threading.Lock()


def _max_threads() -> int:
    return int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]


def _tube_core(tables: Tables) -> tuple[I32Array, I32Array, I32Array]:
    """Return the cells every input's tube covers, per heading cell: (x, count, y ranges).

    Shapes (npsi, c), (npsi,), (npsi, c, 2). A cell whose core touches an obstacle has
    no safe input at all, so the sweeps never need to look at it.
    """
    x0 = tables.tube_x0
    x1 = x0 + tables.tube_n - 1
    npsi, m = x0.shape
    entries: list[list[tuple[int, int, int]]] = []
    for k in range(npsi):
        row = []
        for x in range(int(x0[k].max()), int(x1[k].min()) + 1):
            cols = x - x0[k]
            y0 = int(tables.tube_y[k, np.arange(m), cols, 0].max())
            y1 = int(tables.tube_y[k, np.arange(m), cols, 1].min())
            if y0 <= y1:
                row.append((x, y0, y1))
        entries.append(row)
    width = max(1, max(len(r) for r in entries))
    core_x = np.zeros((npsi, width), dtype=np.int32)
    core_y = np.zeros((npsi, width, 2), dtype=np.int32)
    core_n = np.array([len(r) for r in entries], dtype=np.int32)
    for k, row in enumerate(entries):
        for c, (x, y0, y1) in enumerate(row):
            core_x[k, c] = x
            core_y[k, c] = (y0, y1)
    return core_x, core_n, core_y


class Synthesizer:
    """Solve the reach-avoid game for any obstacle layout on fixed tables.

    Args:
        tables: The abstraction (grid, inputs, tau, margin).
        threads: Threads for the kernel: 1 (the default) runs on the calling thread
            only; None uses all cores. On the shared 2-core machine two threads were
            barely faster when idle and slower under load (the fixed point has one
            barrier per level; a descheduled thread stalls it), and one thread leaves
            a core to the runtime's loop.
        trace_memory: Measure the peak memory of each solve with tracemalloc (slower).
    """

    def __init__(self, tables: Tables, threads: int | None = 1, trace_memory: bool = False) -> None:
        if threads is not None and threads < 1:
            raise GridError(f"threads must be >= 1, got {threads!r}")
        self._tables = tables
        self._threads = threads
        self._trace = trace_memory
        succ = tables.succ
        self._reach_x = np.ascontiguousarray(
            np.stack([succ[..., 0].min(axis=1), succ[..., 1].max(axis=1)], axis=1).astype(np.int32)
        )
        self._e_layers = int((succ[..., 3] - succ[..., 2]).max()) + 1
        tube_h = tables.tube_y[..., 1] - tables.tube_y[..., 0]
        self._f_layers = int(tube_h.max()) + 1
        # Padding (see :mod:`sweep`): rows in x, rows in heading, words in y.
        tube_x1 = tables.tube_x0 + tables.tube_n - 1
        reach = max(
            int(np.abs(succ[..., :2]).max()),
            int(np.abs(tables.tube_x0).max()),
            int(np.abs(tube_x1).max()),
        )
        max_oy = max(int(np.abs(succ[..., 2:]).max()), int(np.abs(tables.tube_y).max()))
        heading_reach = int(np.abs(tables.heading).max())
        self._pads = np.array([reach + 1, heading_reach, 2 + max_oy // 64], dtype=np.int32)
        self._core = _tube_core(tables)

    @property
    def tables(self) -> Tables:
        """Return the tables this synthesizer solves on."""
        return self._tables

    def solve_sets(
        self, obstacles: Sequence[Shape], target: Shape, require_winning: bool = False
    ) -> Controller:
        """Solve for abstract obstacles and target given as shapes in (x, y) (see :meth:`solve`)."""
        grid = self._tables.grid
        obstacles_mask = obstacle_mask(grid, obstacles)
        return self.solve(
            obstacles_mask,
            target_mask(grid, target, obstacles_mask),
            require_winning=require_winning,
        )

    def solve(
        self, obstacles: BoolArray, target: BoolArray, require_winning: bool = False
    ) -> Controller:
        """Solve for cell masks of shape (nx, ny): obstacle cells and target cells.

        Args:
            obstacles: Obstacle cells, shape (nx, ny).
            target: Target cells, shape (nx, ny).
            require_winning: Raise when no cell outside the target wins, instead of
                returning a controller whose `has_winning_start` is False.

        Returns:
            The controller.

        Raises:
            GridError: Masks of the wrong shape.
            NoWinningSetError: `require_winning` and no cell outside the target wins.
        """
        controller = self._solve_traced(obstacles, target)
        if require_winning and not controller.has_winning_start:
            s = controller.stats
            raise NoWinningSetError(
                f"no winning cell outside the target: {s.target_cells!r} target cells, "
                f"{s.free_cells!r} free cells, {int(obstacles.sum())!r} obstacle cells (x, y)"
            )
        return controller

    def _solve_traced(self, obstacles: BoolArray, target: BoolArray) -> Controller:
        if self._trace:
            with _TRACE_LOCK:
                tracemalloc.start()
                try:
                    controller = self._solve(obstacles, target)
                    peak = tracemalloc.get_traced_memory()[1]
                finally:
                    tracemalloc.stop()
            s = controller.stats
            controller.stats = SynthesisStats(
                s.levels, s.seconds, s.winning_cells, s.free_cells, s.target_cells, peak, s.threads
            )
            return controller
        return self._solve(obstacles, target)

    def _solve(self, obstacles: BoolArray, target: BoolArray) -> Controller:
        t = self._tables
        grid = t.grid
        nx, ny, npsi = grid.shape
        if obstacles.shape != (nx, ny) or target.shape != (nx, ny):
            raise GridError(
                f"masks must have shape {(nx, ny)!r}, got {obstacles.shape!r} and {target.shape!r}"
            )
        start = time.perf_counter()
        free = np.ascontiguousarray(~obstacles.astype(bool))
        goal = np.ascontiguousarray(target.astype(bool) & free)
        px, ph, pw = (int(p) for p in self._pads)
        free_words = pack_rows(free)  # (nx, nw)
        nw = free_words.shape[1]
        bits = np.zeros((self._e_layers, nx + 2 * px, npsi + 2 * ph, nw + 2 * pw), dtype=np.uint64)
        free_bits = np.zeros((self._f_layers, nx + 2 * px, nw + 2 * pw), dtype=np.uint64)
        init_bits(pack_rows(goal), free_words, bits, free_bits, px, pw)
        viable = np.empty((nx, npsi, nw), dtype=np.uint64)
        viable_bits(free_bits, *self._core, px, pw, viable)
        values = np.full((nx, ny, npsi), -1, dtype=np.int32)
        values[goal] = 0
        changed = np.repeat(goal.any(axis=1), npsi)
        active = np.empty(nx * npsi, dtype=np.int32)
        new = np.zeros((nx * npsi, nw), dtype=np.uint64)
        threads = 1 if self._threads == 1 else (self._threads or _max_threads())
        args = (
            bits,
            free_bits,
            viable,
            values,
            self._pads,
            t.succ,
            t.heading,
            t.tube_x0,
            t.tube_n,
            t.tube_y,
            self._reach_x,
            changed,
            active,
            new,
        )
        if threads == 1:
            levels = fixed_point_serial(*args)
        else:
            previous = numba.get_num_threads()
            numba.set_num_threads(min(threads, _max_threads()))
            try:
                levels = fixed_point_parallel(*args)
            finally:
                numba.set_num_threads(previous)
        seconds = time.perf_counter() - start
        n_target = int(goal.sum()) * npsi
        stats = SynthesisStats(
            levels=int(levels),
            seconds=seconds,
            winning_cells=int(np.count_nonzero(values >= 0)),
            free_cells=int(free.sum()) * npsi,
            target_cells=n_target,
            threads=threads,
        )
        return Controller(t, values, obstacles.astype(bool), stats)


def synthesize(
    problem: SymbolicProblem,
    *,
    tables: Tables | None = None,
    cache_dir: Path | None = None,
    use_cache: bool = True,
    threads: int | None = 1,
    require_winning: bool = False,
) -> Controller:
    """Build (or load) the tables and solve the problem.

    Args:
        problem: The abstract problem.
        tables: Tables to reuse (re-synthesis for a new layout); built or loaded if None.
        cache_dir: Table cache folder (default :func:`abstraction.default_cache_dir`).
        use_cache: False neither reads nor writes the table cache.
        threads: Kernel threads (see :class:`Synthesizer`).
        require_winning: Raise :class:`NoWinningSetError` when no start outside the
            target wins (otherwise check `Controller.has_winning_start`).

    Raises:
        GridError: Tables built for another grid, inputs, tau or margin.
        NoWinningSetError: `require_winning` and nothing outside the target wins.
    """
    if tables is None:
        tables, _ = tables_for(
            problem.grid,
            problem.inputs,
            problem.tau_s,
            problem.margin,
            cache_dir=cache_dir,
            use_cache=use_cache,
        )
    elif (
        tables.grid != problem.grid
        or tables.inputs.shape != problem.inputs.shape
        or not (
            np.array_equal(tables.inputs, problem.inputs)
            and tables.tau_s == problem.tau_s
            and np.array_equal(tables.margin, problem.margin)
        )
    ):
        raise GridError(f"tables {tables.key!r} were built for another grid, inputs, tau or margin")
    return Synthesizer(tables, threads=threads).solve_sets(
        problem.obstacles, problem.target, require_winning=require_winning
    )
