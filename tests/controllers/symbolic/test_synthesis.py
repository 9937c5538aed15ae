"""The fast solver against the dense baseline and against the game's own equation.

The game (frontier_kernel.py): from (cell, p) the controller may hold p (class-0 tables) or move
to a one-step neighbour u of p (class 1); the state's value is 0 in the target, else
1 + the least, over those inputs with a free tube, of the largest value of the
successor cells in layer u (-1, losing, when no input has all successors winning).
`_bellman` evaluates that right-hand side from the tables, the free masks and the
solved layers alone; a solution that satisfies it everywhere is the BFS fixed point
(each value is reachable and minimal), so the check is a complete second opinion.
"""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.symbolic import (
    Controller,
    Grid,
    GridError,
    NoWinningSetError,
    SymbolicProblem,
    Synthesizer,
    Tables,
    synthesize,
)
from hil.controllers.symbolic.lattice import InputLattice
from hil.controllers.symbolic.reference import dense_fixed_point
from hil.core.shapes import Rect
from tests.controllers.symbolic import tiny

BoolArray = NDArray[np.bool_]
I32Array = NDArray[np.int32]

BIG = 1 << 20


def _layers(controller: Controller) -> list[I32Array]:
    return [controller.layer_values(p) for p in range(controller.tables.n_inputs)]


def _tube_free_map(tables: Tables, free: BoolArray, c: int, k: int, u: int) -> BoolArray:
    """Return (nx, ny): the class-c tube of input u from heading cell k is free."""
    g = tables.grid
    h = int(tables.hull_range_index()[c, k, u])
    pad = 2 + int(
        max(np.abs(tables.tube_x0).max() + tables.tube_n.max(), np.abs(tables.tube_y).max())
    )
    padded = np.zeros((g.nx + 2 * pad, g.ny + 2 * pad), dtype=bool)
    padded[pad : pad + g.nx, pad : pad + g.ny] = free[h]
    ok = np.ones((g.nx, g.ny), dtype=bool)
    for ox, oy in tiny.tube_cells(tables, c, k, u):
        ok &= padded[pad + ox : pad + ox + g.nx, pad + oy : pad + oy + g.ny]
    return ok


def _worst_map(tables: Tables, layer: I32Array, c: int, k: int, u: int) -> NDArray[np.int64]:
    """Return (nx, ny): the largest successor value in `layer` (BIG if one loses)."""
    g = tables.grid
    pad = 2 + int(np.abs(tables.succ).max())
    v = np.where(layer < 0, BIG, layer).astype(np.int64)
    padded = np.full((g.nx + 2 * pad, g.ny + 2 * pad, g.npsi), BIG, dtype=np.int64)
    padded[pad : pad + g.nx, pad : pad + g.ny] = v
    ox0, ox1, oy0, oy1 = (int(a) for a in tables.succ[c, k, u])
    h0, h1 = (int(a) for a in tables.heading[c, u])
    out = np.zeros((g.nx, g.ny), dtype=np.int64)
    for ox in range(ox0, ox1 + 1):
        for oy in range(oy0, oy1 + 1):
            for oh in range(h0, h1 + 1):
                kk = (k + oh) % g.npsi
                out = np.maximum(
                    out, padded[pad + ox : pad + ox + g.nx, pad + oy : pad + oy + g.ny, kk]
                )
    return out


def _bellman(
    tables: Tables, free: BoolArray, target: BoolArray, layers: list[I32Array]
) -> list[I32Array]:
    """Return the game's right-hand side evaluated on `layers`, per reference p."""
    g = tables.grid
    m = tables.n_inputs
    lattice = InputLattice.of(tables.inputs)
    # cost[c][u]: (nx, ny, npsi), the largest successor value of input u under class c
    # where its tube is free, BIG elsewhere.
    cost = np.full((2, m, g.nx, g.ny, g.npsi), BIG, dtype=np.int64)
    for c in (0, 1):
        for u in range(m):
            for k in range(g.npsi):
                worst = _worst_map(tables, layers[u], c, k, u)
                cost[c, u, :, :, k] = np.where(_tube_free_map(tables, free, c, k, u), worst, BIG)
    out = []
    for p in range(m):
        best = cost[0, p].copy()
        for u, cls in tiny.candidates(lattice, p, first=False)[1:]:
            best = np.minimum(best, cost[cls, u])
        expected = np.where(best >= BIG, -1, best + 1).astype(np.int32)
        expected[target] = 0
        out.append(expected)
    return out


def _check_solution(problem: SymbolicProblem, tables: Tables, controller: Controller) -> None:
    """Assert the controller solves the game (its layers satisfy the equation)."""
    free = tiny.flat_free(problem, tables)
    target = problem.target_cells()
    layers = _layers(controller)
    for p, (got, want) in enumerate(
        zip(layers, _bellman(tables, free, target, layers), strict=True)
    ):
        np.testing.assert_array_equal(got, want, err_msg=f"layer {p}")
    values = np.stack(layers)
    assert controller.stats.levels == values.max()
    levels = np.unique(values[values >= 0])
    np.testing.assert_array_equal(levels, np.arange(levels.max() + 1))


def _check_dense(problem: SymbolicProblem, tables: Tables) -> Controller:
    """Assert serial and threaded solves equal the dense solver; return the serial one."""
    free = tiny.flat_free(problem, tables)
    dense, levels = dense_fixed_point(tables, free, problem.target_cells())
    serial = Synthesizer(tables, memo=False, use_cache=False).solve_problem(problem)
    threaded = Synthesizer(tables, threads=2, memo=False, use_cache=False).solve_problem(problem)
    assert (serial.stats.threads, threaded.stats.threads) == (1, 2)
    assert serial.stats.levels == threaded.stats.levels == levels
    for p in range(tables.n_inputs):
        np.testing.assert_array_equal(serial.layer_values(p), dense[p], err_msg=f"layer {p}")
        np.testing.assert_array_equal(threaded.layer_values(p), dense[p], err_msg=f"layer {p}")
    return serial


@pytest.mark.parametrize(("scale", "npsi"), [(0.0, 12), (1.0, 24), (2.0, 24)])
def test_fast_solver_equals_dense_and_solves_the_game(scale: float, npsi: int) -> None:
    the_budget = tiny.zero_budget() if scale == 0.0 else tiny.budget(scale)
    problem = tiny.problem(the_budget, grid=replace(tiny.GRID, npsi=npsi))
    tables, _ = problem.tables(use_cache=False)
    controller = _check_dense(problem, tables)
    _check_solution(problem, tables, controller)
    assert controller.stats.levels >= 2
    assert controller.has_winning_start or scale > 1.0


def test_a_wall_across_the_arena_makes_the_far_side_losing() -> None:
    wall = Rect(-0.2, 0.0, -1.0, 1.0)
    problem = tiny.problem(tiny.zero_budget(), obstacles=(wall,), grid=replace(tiny.GRID, npsi=12))
    tables, _ = problem.tables(use_cache=False)
    controller = _check_dense(problem, tables)
    g = problem.grid
    x_lo = g.x_min_m + np.arange(g.nx) * g.cell_x_m
    far = x_lo >= wall.x_max_m
    near = x_lo + g.cell_x_m <= wall.x_min_m - problem.inflation_m
    for p in range(tables.n_inputs):
        v = controller.layer_values(p)
        assert np.all(v[far] == -1), p
        assert np.any(v[near] > 0), p
    assert controller.value((1.0, 0.0, 0.0)) == np.inf
    assert controller.safe_inputs((1.0, 0.0, 0.0)).shape == (0, 3)
    # Without the wall the far side wins somewhere.
    empty = problem.with_obstacles(())
    free = Synthesizer(tables, memo=False, use_cache=False).solve_problem(empty)
    assert np.any(free.values[far] > 0)


def test_fast_solver_equals_dense_when_headings_wrap_and_rows_span_two_words() -> None:
    # A yaw rate of 3.3 rad/s turns 6.6 rad in tau: heading offsets 8 and 9 on a grid of
    # 8 heading cells, so the solver reads padding rows that wrap more than once; and
    # ny = 70 puts every row across two machine words.
    grid = Grid(-1.5, -1.0, 0.1, 0.025, 20, 70, 8)  # word boundary at y = 0.6
    axes = (np.array([0.0, 0.1]), np.array([-0.05, 0.0, 0.05]), np.array([-3.3, 0.0, 3.3]))
    problem = tiny.problem(
        tiny.zero_budget(),
        grid=grid,
        the_inputs=tiny.inputs(axes),
        obstacles=(Rect(-0.3, -0.1, 0.2, 0.4),),
        target=Rect(-1.0, -0.5, 0.45, 0.75),
    )
    tables, _ = problem.tables(use_cache=False)
    assert tables.heading.max() > grid.npsi
    controller = _check_dense(problem, tables)
    _check_solution(problem, tables, controller)
    assert controller.stats.levels >= 3
    # Winning cells on both sides of the word boundary at j = 64.
    rest = controller.values
    assert np.any(rest[:, 60:64] > 0)
    assert np.any(rest[:, 64:] >= 0)


def test_every_winning_state_has_a_listed_input(controller: Controller) -> None:
    rng = np.random.default_rng(4)
    m = controller.tables.n_inputs
    seen = 0
    for p in rng.choice(m, 8, replace=False):
        v = controller.layer_values(int(p))
        for cell in np.argwhere(v > 0)[::3]:
            c = (int(cell[0]), int(cell[1]), int(cell[2]))
            listed = controller.safe_input_indices_at(c, int(p))
            assert listed.size > 0, (c, p)
            seen += 1
    assert seen > 500


def test_target_alone_has_value_zero(problem: SymbolicProblem, controller: Controller) -> None:
    target = problem.target_cells()
    assert target.any()
    for p in range(controller.tables.n_inputs):
        v = controller.layer_values(p)
        np.testing.assert_array_equal(v == 0, target, err_msg=f"layer {p}")
    assert controller.stats.target_cells == int(target.sum())
    inside = (-1.0, 0.1, 0.2)  # the target is [-1.3, -0.7] x [-0.3, 0.5]
    assert controller.value(inside) == 0.0
    assert controller.safe_inputs(inside).shape == (0, 3)


def test_stats_count_the_sets(problem: SymbolicProblem, controller: Controller) -> None:
    s = controller.stats
    assert s.winning_cells == int((controller.values >= 0).sum())
    assert s.free_cells == int(problem.heading_free().sum())
    assert 0.0 < s.winning_fraction < 1.0
    assert s.seconds > 0.0


def test_more_obstacles_only_shrink_the_winning_sets(
    zero_problem: SymbolicProblem, zero_tables: Tables, zero_controller: Controller
) -> None:
    synthesizer = Synthesizer(zero_tables, memo=False, use_cache=False)
    empty = synthesizer.solve_problem(zero_problem.with_obstacles(()))
    more = synthesizer.solve_problem(
        zero_problem.with_obstacles((*zero_problem.obstacles, Rect(-0.6, -0.4, 0.4, 1.0)))
    )
    assert not empty.obstacles.any()
    assert empty.stats.winning_cells > zero_controller.stats.winning_cells
    assert zero_controller.stats.winning_cells > more.stats.winning_cells
    for p in range(zero_tables.n_inputs):
        a, b, c = (x.layer_values(p) for x in (empty, zero_controller, more))
        for bigger, smaller in ((a, b), (b, c)):
            won = smaller >= 0
            assert np.all(bigger[won] >= 0), p
            assert np.all(bigger[won] <= smaller[won]), p


def test_each_new_layout_starts_from_the_last_ones_viable_words(
    problem: SymbolicProblem, tables: Tables
) -> None:
    """One synthesizer through a run of layouts recomputes only the columns that changed.

    Its viable words equal a fresh synthesizer's for every layout, and every layout's
    values solve that layout's game (the equation, from the free masks alone).
    """
    synthesizer = Synthesizer(tables, memo=False, use_cache=False)
    moved = (Rect(0.2, 0.4, -0.9, 0.2), Rect(0.3, 0.5, -0.9, 0.2))
    layouts = [
        problem,
        problem.with_obstacles(moved[:1]),
        problem.with_obstacles(moved[1:]),
        problem.with_obstacles((*moved[1:], Rect(-0.2, 0.0, 0.6, 1.0))),
        problem.with_obstacles(()),
        problem,
    ]
    words = []
    for layout in layouts:
        controller = synthesizer.solve_problem(layout)
        fresh = Synthesizer(tables, memo=False, use_cache=False).solve_problem(layout)
        np.testing.assert_array_equal(controller.viable_words, fresh.viable_words)
        _check_solution(layout, tables, controller)
        words.append(controller.viable_words)
    assert not np.array_equal(words[0], words[1])  # the layouts do differ
    assert words[-1] is not words[0]  # a new array: the first controller's is never written


def test_no_winning_cell_is_reported(problem: SymbolicProblem, tables: Tables) -> None:
    cover = Rect(-1.5, -0.5, -1.0, 1.0)  # over the whole target
    covered = problem.with_obstacles((cover,))
    controller = Synthesizer(tables, memo=False, use_cache=False).solve_problem(covered)
    assert not controller.has_winning_start
    assert controller.stats.winning_cells == 0
    assert controller.stats.target_cells == 0
    assert controller.stats.winning_fraction == 0.0
    for p in range(tables.n_inputs):
        assert np.all(controller.layer_values(p) == -1)
    assert controller.safe_inputs((1.0, 0.5, 0.0)).shape == (0, 3)
    with pytest.raises(NoWinningSetError, match="no winning cell outside the target from rest"):
        Synthesizer(tables).solve_problem(covered, require_winning=True)
    with pytest.raises(NoWinningSetError, match="0 target cells"):
        synthesize(covered, tables=tables, require_winning=True)


def test_resynthesis_reuses_tables_and_runs_in_a_thread(
    problem: SymbolicProblem, tables: Tables, controller: Controller
) -> None:
    moved = problem.with_obstacles((problem.obstacles[0].translate(-0.3, 0.0),))
    synthesizer = Synthesizer(tables, memo=False, use_cache=False)
    results: list[Controller] = []
    worker = threading.Thread(target=lambda: results.append(synthesizer.solve_problem(moved)))
    worker.start()
    lookups = 0
    while worker.is_alive():  # the lookup keeps working meanwhile
        controller.safe_inputs((0.8, -0.5, 2.0), 4)
        lookups += 1
        worker.join(0.001)
    assert len(results) == 1
    assert lookups > 0
    assert results[0].tables is tables
    again = synthesize(moved, tables=tables, threads=1)
    assert again.tables is tables
    for p in range(0, tables.n_inputs, 5):
        np.testing.assert_array_equal(results[0].layer_values(p), again.layer_values(p))
    assert not np.array_equal(results[0].values, controller.values)


def test_the_memo_returns_the_same_controller_for_the_same_masks(
    problem: SymbolicProblem, tables: Tables
) -> None:
    first = Synthesizer(tables).solve_problem(problem)
    assert Synthesizer(tables).solve_problem(problem) is first  # another synthesizer too
    # Same masks from other shapes: the memo keys on masks, not on shapes.
    assert Synthesizer(tables).solve_problem(replace(problem, name="renamed")) is first
    moved = problem.with_obstacles((problem.obstacles[0].translate(-0.3, 0.0),))
    other = Synthesizer(tables).solve_problem(moved)
    assert other is not first
    assert not np.array_equal(other.values, first.values)
    fresh = Synthesizer(tables, memo=False, use_cache=False).solve_problem(problem)
    assert fresh is not first
    np.testing.assert_array_equal(fresh.values, first.values)
    # Other tables (another budget) with the same masks are not confused with these.
    wider_problem = replace(problem, budget=tiny.budget(2.0))
    wider, _ = wider_problem.tables(use_cache=False)
    assert Synthesizer(wider).solve_problem(wider_problem) is not first
    # The memo holds the last two layouts solved or reused: a third evicts the oldest.
    first = Synthesizer(tables).solve_problem(problem)
    other = Synthesizer(tables).solve_problem(moved)
    assert Synthesizer(tables).solve_problem(problem) is first  # now the newest
    Synthesizer(tables).solve_problem(problem.with_obstacles(()))  # evicts `other`
    assert Synthesizer(tables).solve_problem(problem) is first
    assert Synthesizer(tables).solve_problem(moved) is not other


def test_bad_masks_and_arguments_are_refused(problem: SymbolicProblem, tables: Tables) -> None:
    synthesizer = Synthesizer(tables)
    g = tables.grid
    n_ranges = tables.hull_psi.reshape(-1, 2).shape[0]
    free = np.ones((n_ranges, g.nx, g.ny), dtype=bool)
    target = np.zeros(g.shape, dtype=bool)
    obstacles = np.zeros((g.nx, g.ny), dtype=bool)
    with pytest.raises(GridError, match="masks must have shapes"):
        synthesizer.solve(free[:-1], target, obstacles)
    with pytest.raises(GridError, match="masks must have shapes"):
        synthesizer.solve(free, target[..., :-1], obstacles)
    with pytest.raises(GridError, match="masks must have shapes"):
        synthesizer.solve(free[:, :-1], target, obstacles)
    with pytest.raises(GridError, match="threads"):
        Synthesizer(tables, threads=0)
    with pytest.raises(GridError, match="grid"):
        synthesizer.solve_problem(replace(problem, grid=replace(g, nx=g.nx + 1)))
    # Right shapes, nothing to reach: nothing wins.
    nothing = synthesizer.solve(free, target, obstacles)
    assert not nothing.has_winning_start
    assert nothing.stats.levels == 0
