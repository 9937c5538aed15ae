"""Reach-avoid synthesis over (cell, current reference) on the cached tables.

One call per obstacle layout. The kernels (:mod:`sweep`) release the GIL, so the runtime
can re-synthesize in a background thread while its loop runs (on a 2-core machine,
`threads=1` leaves a core to the loop).
"""

from __future__ import annotations

import threading
import time
import tracemalloc
from collections import OrderedDict, deque
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numba
import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.abstraction import N_CLASSES, Tables
from hil.controllers.symbolic.controller import Controller, SynthesisStats
from hil.controllers.symbolic.errors import GridError, NoWinningSetError
from hil.controllers.symbolic.frontier_kernel import (
    advance_level_parallel,
    advance_level_serial,
    init_layers,
    start_levels,
)
from hil.controllers.symbolic.kernels import pack_rows
from hil.controllers.symbolic.lattice import InputLattice
from hil.controllers.symbolic.levels import LevelSolver, Outputs, Scratch, Watch
from hil.controllers.symbolic.planes_kernel import from_sweep_layout, nested_classes
from hil.controllers.symbolic.problem import SymbolicProblem
from hil.controllers.symbolic.safety import solve_safe_set
from hil.controllers.symbolic.sources import ControllerSources
from hil.controllers.symbolic.store import ControllerStore, solve_key
from hil.controllers.symbolic.stored import StoredControllers
from hil.controllers.symbolic.viable import ViableWords, cell_major
from hil.core.arrays import BoolArray, U64Array
from hil.core.memory import require_bytes

I32Array = NDArray[np.int32]

__all__ = ["KERNELS", "N_PLANES", "Synthesizer", "Watch", "synthesize"]

KERNELS = ("planes", "frontier")
"""The fixed-point kernels: :mod:`planes_kernel` (the default; the frontier kernel serves
tables whose class-1 boxes do not contain class 0's) and the frontier kernel (the reference)."""

N_PLANES = 8
"""Bit planes of the values: at most 255 levels."""

_TRACE_LOCK = threading.Lock()

MEMO_SIZE = 2
"""Solved controllers a process keeps, keyed by tables and masks (:meth:`solve_problem`)."""

_MEMO: OrderedDict[str, Controller] = OrderedDict()
_MEMO_LOCK = threading.Lock()


def _max_threads() -> int:
    return int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]


class Synthesizer:
    """Solve the reach-avoid game over (cell, reference) for any obstacle layout.

    Args:
        tables: The abstraction (grid, inputs, tau, budget).
        threads: Threads for the kernel: 1 (the default) runs on the calling thread
            only; None uses all cores.
        trace_memory: Measure the peak memory of each solve with tracemalloc (slower).
        memo: Reuse a controller this process already solved for the same tables and
            masks (the last :data:`MEMO_SIZE`): simulated runs and campaigns solve the
            same layout over and over.
        use_cache: Read a controller solved before (by any process) from the store on
            disk, and write each solve there (:mod:`~hil.controllers.symbolic.store`).
            Benchmarks turn it and `memo` off, so that every call solves.
        cache_dir: The table cache folder whose ``controllers/`` is the store
            (:func:`~hil.controllers.symbolic.abstraction.default_cache_dir` if None).
        kernel: One of :data:`KERNELS`; both give identical winning sets and values.
        prepare_outputs: After each planes solve, once its caller has taken the full
            controller and asks for more, allocate and map the next solve's result
            arrays (:class:`~hil.controllers.symbolic.levels.Outputs`, about 320 MB at
            the paper grid), so that the next layout's solve starts without page faults
            (the re-synthesis beside a vessel's loop), and a copy of its viable words
            for the next layout to start from (:meth:`ViableWords.prepare`).
    """

    def __init__(
        self,
        tables: Tables,
        threads: int | None = 1,
        trace_memory: bool = False,
        memo: bool = True,
        use_cache: bool = True,
        cache_dir: Path | None = None,
        kernel: str = "planes",
        prepare_outputs: bool = False,
    ) -> None:
        if threads is not None and threads < 1:
            raise GridError(f"threads must be >= 1, got {threads!r}")
        if kernel not in KERNELS:
            raise GridError(f"kernel must be one of {KERNELS!r}, got {kernel!r}")
        self._kernel = kernel
        self._tables = tables
        self._lattice = InputLattice.of(tables.inputs)
        self._threads = threads
        self._trace = trace_memory
        self._memo = memo and not trace_memory
        self._stored = StoredControllers(
            ControllerStore.default(cache_dir) if use_cache else None, tables, self._lattice,
            N_PLANES,
        )
        self._reuse_lock = threading.Lock()
        self._spare: Scratch | None = None
        """The working arrays of the last finished planes solve (the next one reuses them)."""
        self._prepare = prepare_outputs and kernel == "planes"
        self._ready: Outputs | None = None
        self.sources = ControllerSources()
        succ = tables.succ
        self._reach = np.ascontiguousarray(
            np.stack([succ[..., 0].min(axis=0), succ[..., 1].max(axis=0)], axis=-1).astype(np.int32)
        )
        hd = tables.heading
        self._h_reach = np.ascontiguousarray(
            np.stack([hd[..., 0].min(axis=0), hd[..., 1].max(axis=0)], axis=-1).astype(np.int32)
        )
        tube_x1 = tables.tube_x0 + tables.tube_n - 1
        reach_x = max(
            int(np.abs(succ[..., :2]).max()),
            int(np.abs(tables.tube_x0).max()),
            int(np.abs(tube_x1).max()),
        )
        max_oy = max(int(np.abs(succ[..., 2:]).max()), int(np.abs(tables.tube_y).max()))
        self._pads = np.array(
            [reach_x + 1, int(np.abs(hd).max()), 2 + max_oy // 64], dtype=np.int32
        )
        if int((succ[..., 3] - succ[..., 2]).max()) >= 64:
            raise GridError(
                "successor boxes span more than 64 cells along y: the grid is too fine for "
                "the deviation budget; use a coarser [grid] cell_m"
            )
        self._viable = ViableWords(tables, self._pads)
        """The viable words of a layout, from the last layout's (a new layout starts there)."""
        flat = tables.hull_psi.reshape(-1, 2)
        self._psi_lo = np.ascontiguousarray(flat[:, 0])
        self._psi_hi = np.ascontiguousarray(flat[:, 1])

    @property
    def solve_bytes(self) -> int:
        """Return about how many bytes one solve allocates (its masks, words and result)."""
        nx, ny, npsi = self._tables.grid.shape
        m = self._tables.n_inputs
        px, ph, pw = (int(p) for p in self._pads)
        nw = (ny + 63) // 64
        n_ranges = int(self._psi_lo.shape[0])
        rows_words = m * nx * npsi * nw * 8  # one (m, n_rows, nw) array of words
        return int(
            n_ranges * nx * (ny + 8 * nw)  # free masks and their words
            + N_CLASSES * rows_words  # viable
            + m * (nx + 2 * px) * (npsi + 2 * ph) * (nw + 2 * pw) * 8  # W
            + 3 * rows_words  # B, new A, new B
            + N_PLANES * rows_words  # values
            + 2 * rows_words // 8  # kill
            + 2 * nx * ny * npsi * 4  # the controller's values from rest, and a layer's
            + (self._viable.f_layers + 1) * (nx + 2 * px) * (nw + 2 * pw) * 8
            + m * npsi * (nw + 2 * pw) * (nx + 2 * px) * 8 * (3 if self._prepare else 1)
            + ((N_PLANES + N_CLASSES) * rows_words if self._prepare else 0)  # the next
            # solve's outputs and viable words, prepared
            + (3 + N_PLANES + 2 * (self._threads or _max_threads()) / npsi) * rows_words
        )

    @property
    def tables(self) -> Tables:
        """Return the tables this synthesizer solves on."""
        return self._tables

    @property
    def lattice(self) -> InputLattice:
        """Return the input lattice (which reference may follow which)."""
        return self._lattice

    def solve_problem(self, problem: SymbolicProblem, require_winning: bool = False) -> Controller:
        """Solve a problem on these tables: its obstacles, walls, hull and target.

        Raises:
            GridError: The problem's grid is not the tables'.
            NoWinningSetError: `require_winning` and no state outside the target wins from rest.
        """
        return deque(self.solve_stages(problem, require_winning=require_winning), maxlen=1)[0]

    def solve_stages(
        self,
        problem: SymbolicProblem,
        watch: Watch | None = None,
        require_winning: bool = False,
    ) -> Iterator[Controller]:
        """Solve a problem, yielding an early controller once it covers `watch`, then the full one.

        The early controller (``stats.complete`` False) holds every state of value up to
        the level at which the watched state joined, with its final value and safe
        inputs; states of higher values are not winning in it yet. It is yielded only
        when the watched state joins before the fixed point; a controller this process
        already solved is yielded at once, complete.

        Raises:
            GridError: The problem's grid is not the tables'.
            NoWinningSetError: `require_winning` and no state outside the target wins
                from rest (raised after the full solve, before it is yielded).
        """
        if problem.grid != self._tables.grid:
            raise GridError("the problem's grid is not the tables' grid")
        start = time.perf_counter()
        free = problem.free_masks(self._psi_lo, self._psi_hi)
        at_rest = problem.heading_free()
        target = problem.target_cells(at_rest)
        obstacles = problem.inflated_obstacle_mask()
        stored = self._stored if self._stored.enabled else None
        key = ""
        if self._memo or stored is not None:
            key = solve_key(self._tables.key, (free, target, obstacles))
        controller = None
        if self._memo:
            with _MEMO_LOCK:
                controller = _MEMO.get(key)
                if controller is not None:
                    _MEMO.move_to_end(key)
                    self.sources.memory += 1
        if controller is None and stored is not None:
            controller = stored.load(key, self._pads, target, obstacles, int(at_rest.sum()))
            if controller is not None:
                self.sources.store += 1
                self._remember(key, controller)
        if controller is None:
            self.sources.solved += 1
            if self._trace:
                controller = self._solve_traced(free, target, obstacles, int(at_rest.sum()), start)
            else:
                for stage in self.stages(free, target, obstacles, int(at_rest.sum()), start, watch):
                    if not stage.stats.complete:
                        yield stage  # an early controller is neither remembered nor stored
                    controller = stage
            assert controller is not None
            self._remember(key, controller)
            if stored is not None:
                stored.write(key, controller)
        if require_winning and not controller.has_winning_start:
            s = controller.stats
            raise NoWinningSetError(
                f"no winning cell outside the target from rest: {s.target_cells!r} target "
                f"cells, {s.free_cells!r} free cells, {int(obstacles.sum())!r} obstacle cells"
            )
        yield controller
        if self._prepare:
            self._viable.prepare()
            if self._ready is None:
                nx, ny, npsi = self._tables.grid.shape
                ready = Outputs.allocate(self._tables.n_inputs, npsi, (ny + 63) // 64, nx,
                                         self._pads, N_PLANES)
                with self._reuse_lock:
                    self._ready = ready

    def start_from(self, problem: SymbolicProblem) -> None:
        """Make `problem`'s layout the one the next solve starts from, without solving it.

        A solve computes only the viable words that its layout changed against the last
        layout this synthesizer saw (:meth:`_viable`); a benchmark of "a new layout after
        this one" sets the previous layout here.
        """
        self._viable.words(problem.free_masks(self._psi_lo, self._psi_hi))
        if self._prepare:
            self._viable.prepare()

    def wait_stored(self) -> None:
        """Block until every controller this synthesizer solved is written to the store."""
        self._stored.wait()

    def _remember(self, key: str, controller: Controller) -> None:
        if self._memo:
            with _MEMO_LOCK:
                _MEMO[key] = controller
                while len(_MEMO) > MEMO_SIZE:
                    _MEMO.popitem(last=False)

    def _solve_traced(
        self,
        free: BoolArray,
        target: BoolArray,
        obstacles: BoolArray,
        free_cells: int,
        start: float,
    ) -> Controller:
        with _TRACE_LOCK:
            tracemalloc.start()
            try:
                controller = self.solve(free, target, obstacles, free_cells, start)
                peak = tracemalloc.get_traced_memory()[1]
            finally:
                tracemalloc.stop()
        controller.stats = replace(controller.stats, peak_bytes=peak)
        return controller

    def _words(self, free: BoolArray, target: BoolArray, threads: int) -> tuple[U64Array, U64Array]:
        """Return the viable words (3, m, npsi, nw, nx) and goal words (nx, npsi, nw)."""
        nx, ny, npsi = self._tables.grid.shape
        nw = (ny + 63) // 64
        goal_cells = np.ascontiguousarray(np.transpose(target, (0, 2, 1)).reshape(-1, ny))
        goal = pack_rows(goal_cells).reshape(nx, npsi, nw)
        return self._viable.words(free, threads), goal

    def _level_solver(self, viable: U64Array, goal: U64Array, threads: int) -> LevelSolver:
        t, axes = self._tables, self._lattice.axes
        with self._reuse_lock:
            scratch, self._spare = self._spare, None
            outputs, self._ready = self._ready, None
        return LevelSolver(
            goal, viable, self._pads, t.succ, t.heading,
            (len(axes[0]), len(axes[1]), len(axes[2])), N_PLANES, threads, scratch, outputs,
        )  # fmt: skip

    def _frontier_stages(
        self, viable: U64Array, goal: U64Array, threads: int, watch: Watch | None
    ) -> Iterator[tuple[U64Array, U64Array, int, bool]]:
        """Run :mod:`sweep`'s frontier kernel one level per call.

        Yields (W, planes, levels, complete): once the watched state joined (an early
        stage, W a copy), then at the fixed point.
        """
        t = self._tables
        nx, ny, npsi = t.grid.shape
        m = t.n_inputs
        px, ph, pw = (int(p) for p in self._pads)
        nw = (ny + 63) // 64
        W = np.zeros((m, nx + 2 * px, npsi + 2 * ph, nw + 2 * pw), dtype=np.uint64)
        n_rows = nx * npsi
        n_rw = (n_rows + 63) // 64
        chmask = np.zeros((m, n_rw), dtype=np.uint64)
        init_layers(goal, W, px, ph, pw, chmask)
        b_set = np.zeros((m, n_rows, nw), dtype=np.uint64)
        planes = np.zeros((m, nx, npsi, nw, N_PLANES), dtype=np.uint64)
        umask = np.zeros((m, n_rw), dtype=np.uint64)
        has_a = np.zeros((m, n_rw), dtype=np.uint64)
        has_b = np.zeros((m, n_rw), dtype=np.uint64)
        new_a = np.empty((m, n_rows, nw), dtype=np.uint64)
        new_b = np.empty((m, n_rows, nw), dtype=np.uint64)
        kill = np.zeros((2, m, n_rows, nw), dtype=np.uint8)
        lat = self._lattice
        args = (
            W, b_set, cell_major(viable), planes, self._pads, t.succ, t.heading, self._reach,
            self._h_reach, lat.neighbours, lat.n_neighbours, chmask, umask, has_a, has_b,
            new_a, new_b, kill,
        )  # fmt: skip
        advance = advance_level_serial if threads == 1 else advance_level_parallel
        previous = numba.get_num_threads()
        if threads > 1:
            numba.set_num_threads(min(threads, _max_threads()))
        try:
            level = 0
            changed = start_levels(W, planes, self._reach, self._h_reach, chmask, umask)
            watching = watch is not None
            while True:
                if watching and watch is not None and watch.covered_by(W, self._pads):
                    watching = False
                    if changed > 0:
                        # States of value <= level are final; the solve goes on in W, so
                        # the early controller keeps its own copy.
                        yield (*self._planes_layout(W, planes), level, False)
                if changed == 0:
                    break
                if level + 1 > 2**N_PLANES - 1:
                    break  # capped: see _planes_stages
                changed = advance(level, *args)
                if changed > 0:
                    level += 1
        finally:
            if threads > 1:
                numba.set_num_threads(previous)
        yield (*self._planes_layout(W, planes), level, True)

    def _planes_layout(self, W: U64Array, planes: U64Array) -> tuple[U64Array, U64Array]:
        """Return :mod:`sweep`'s W and planes as new arrays in the Controller's layout."""
        m, nx, npsi, nw, n_planes = planes.shape
        px, _, pw = (int(p) for p in self._pads)
        winning = np.zeros((m, npsi, nw + 2 * pw, nx + 2 * px), dtype=np.uint64)
        values = np.empty((m, npsi, nw, n_planes, nx), dtype=np.uint64)
        from_sweep_layout(W, planes, self._pads, winning, values)
        return winning, values

    def _planes_stages(
        self, solver: LevelSolver, watch: Watch | None
    ) -> Iterator[tuple[U64Array, U64Array, int, bool]]:
        """Run :mod:`planes_kernel` (see :meth:`_frontier_stages`); each stage exported."""
        if watch is not None:
            i, j, k = watch.cell
            while not solver.done:
                if solver.joined(watch.reference, i, j, k):
                    W, planes = solver.export()
                    yield W, planes, solver.level, False
                    break
                if solver.advance() < 0:
                    break
        # A fixed point of more levels than the value planes hold stops at their last
        # level: every state joined so far keeps its value and safe inputs (sound), the
        # states farther from the target are left out (not winning), as in an early
        # controller; the safety controller still covers them.
        solver.solve()
        with self._reuse_lock:
            self._spare = solver.scratch
        W, planes = solver.export()
        yield W, planes, solver.level, True

    def solve(
        self,
        free: BoolArray,
        target: BoolArray,
        obstacles: BoolArray,
        free_cells: int | None = None,
        start: float | None = None,
    ) -> Controller:
        """Solve for masks: free cells per hull range, target cells, inflated obstacles.

        Args:
            free: Cells free for the hull over each of the tables' heading ranges, shape
                (n_ranges, nx, ny) (``tables.hull_psi`` flattened).
            target: Target cells, shape (nx, ny, npsi).
            obstacles: Cells touching an inflated obstacle, shape (nx, ny) (pictures).
            free_cells: States the hull may occupy at rest (the winning fraction's
                denominator); cells off the inflated obstacles times npsi if None.
            start: perf_counter() when the solve began (masks included), if earlier.

        Raises:
            GridError: Masks of the wrong shape.
            MemoryError: The solve needs more memory than this process can allocate
                (:attr:`solve_bytes`; checked first: Linux would hand it out and kill
                the process when touched).
        """
        return deque(self.stages(free, target, obstacles, free_cells, start), maxlen=1)[0]

    def stages(
        self,
        free: BoolArray,
        target: BoolArray,
        obstacles: BoolArray,
        free_cells: int | None = None,
        start: float | None = None,
        watch: Watch | None = None,
    ) -> Iterator[Controller]:
        """Solve for masks (see :meth:`solve`), yielding the early controller of `watch` first.

        The fixed point runs one BFS level at a time; after the level at which the
        watched state joins, an early controller (``stats.complete`` False) is yielded,
        then the solve goes on to the fixed point and yields the full controller.
        """
        t = self._tables
        grid = t.grid
        nx, ny, npsi = grid.shape
        m = t.n_inputs
        n_ranges = self._psi_lo.shape[0]
        if free.shape != (n_ranges, nx, ny) or target.shape != (nx, ny, npsi):
            raise GridError(
                f"masks must have shapes {(n_ranges, nx, ny)!r} and {(nx, ny, npsi)!r}, "
                f"got {free.shape!r} and {target.shape!r}"
            )
        require_bytes(self.solve_bytes, f"a solve on the {nx} x {ny} x {npsi} grid, {m} inputs")
        t0 = time.perf_counter() if start is None else start
        threads = 1 if self._threads == 1 else (self._threads or _max_threads())
        viable, goal = self._words(free, target, threads)
        use_planes = self._kernel == "planes" and nested_classes(t.succ, t.heading, viable)
        solver = self._level_solver(viable, goal, threads) if use_planes else None
        stages = (self._planes_stages(solver, watch) if solver is not None
                  else self._frontier_stages(viable, goal, threads, watch))
        for W, planes, levels, complete in stages:
            safe = None
            if complete:
                lat = self._lattice
                with self._reuse_lock:  # this solve's arrays, held back from the next solve
                    mine = solver is not None and solver.scratch is self._spare
                    spare, self._spare = (self._spare, None) if mine else (None, self._spare)
                safe = solve_safe_set(viable, self._pads, t.succ, t.heading, lat.neighbours,
                                      lat.n_neighbours, threads, spare).bits
                with self._reuse_lock:
                    self._spare = spare if spare is not None else self._spare
            yield self._controller(
                W, planes, viable, levels, target, obstacles, free_cells, t0, threads, complete,
                safe,
            )  # fmt: skip

    def begin(self, free: BoolArray, target: BoolArray) -> LevelSolver:
        """Start a solve driven one BFS level per call (masks as :meth:`solve`'s).

        ``solver.advance()`` joins the states of value ``solver.level + 1`` (returns 0 at
        the fixed point); :meth:`controller_of` makes a controller of the states joined so
        far at any point (every state of value <= ``solver.level`` is final).

        Raises:
            GridError: Masks of the wrong shape, or tables whose class-1 boxes do not
                contain class 0's (only the frontier kernel solves those).
        """
        t = self._tables
        nx, ny, npsi = t.grid.shape
        if free.shape != (self._psi_lo.shape[0], nx, ny) or target.shape != (nx, ny, npsi):
            raise GridError(f"masks of shapes {free.shape!r}, {target.shape!r} do not fit the grid")
        threads = 1 if self._threads == 1 else (self._threads or _max_threads())
        viable, goal = self._words(free, target, threads)
        if not nested_classes(t.succ, t.heading, viable):
            raise GridError("class-1 boxes do not contain class 0's: use the frontier kernel")
        return self._level_solver(viable, goal, threads)

    def controller_of(
        self,
        solver: LevelSolver,
        target: BoolArray,
        obstacles: BoolArray,
        free_cells: int | None = None,
        start: float | None = None,
    ) -> Controller:
        """Return a controller of the states `solver` joined so far (a copy: it may go on).

        Its stats' levels is ``solver.level``; seconds count from `start` if given.
        """
        W, planes = solver.export()
        t0 = time.perf_counter() if start is None else start
        return self._controller(
            W, planes, solver.viable, solver.level, target, obstacles, free_cells, t0,
            solver.threads,
        )  # fmt: skip

    def _controller(
        self,
        W: U64Array,
        planes: U64Array,
        viable: U64Array,
        levels: int,
        target: BoolArray,
        obstacles: BoolArray,
        free_cells: int | None,
        t0: float,
        threads: int,
        complete: bool = True,
        safe: U64Array | None = None,
    ) -> Controller:
        npsi = self._tables.grid.npsi
        seconds = time.perf_counter() - t0
        return Controller(
            self._tables, self._lattice, W, planes, viable, self._pads, obstacles.astype(bool),
            SynthesisStats(
                levels=int(levels), seconds=seconds, winning_cells=0,
                free_cells=int((~obstacles).sum()) * npsi if free_cells is None else free_cells,
                target_cells=int(target.sum()),
                threads=threads, complete=complete,
            ), safe,
        )  # fmt: skip


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
            target wins from rest.

    Raises:
        GridError: Tables built for another grid, inputs, tau or budget.
        NoWinningSetError: `require_winning` and nothing outside the target wins.
    """
    if tables is None:
        tables, _ = problem.tables(cache_dir=cache_dir, use_cache=use_cache)
    elif (
        tables.grid != problem.grid
        or tables.inputs.shape != problem.inputs.shape
        or not (
            np.array_equal(tables.inputs, problem.inputs)
            and tables.tau_s == problem.tau_s
            and tables.late_s == problem.late_s
            and tables.budget_key == problem.budget.digest()
        )
    ):
        raise GridError(f"tables {tables.key!r} were built for another grid, inputs, tau or budget")
    return Synthesizer(tables, threads=threads).solve_problem(
        problem, require_winning=require_winning
    )
