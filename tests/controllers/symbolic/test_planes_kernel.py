"""The bit-plane kernel (planes_kernel, levels) against the frontier kernel (sweep).

Both must give bit-identical winning words (padding included) and value planes; the
level-at-a-time solver must, after any level L, hold exactly the states of value <= L.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from hil.controllers.symbolic import Controller, Grid, GridError, SymbolicProblem, Synthesizer
from hil.controllers.symbolic.kernels import layer_values
from hil.controllers.symbolic.levels import LevelSolver
from hil.controllers.symbolic.planes_kernel import nested_classes
from hil.core.shapes import Rect
from tests.controllers.symbolic import tiny


def _random_obstacles(rng: np.random.Generator, n: int) -> tuple[Rect, ...]:
    out = []
    for _ in range(n):
        x = rng.uniform(-1.4, 1.0)
        y = rng.uniform(-0.9, 0.7)
        out.append(Rect(x, x + rng.uniform(0.05, 0.3), y, y + rng.uniform(0.05, 0.3)))
    return tuple(out)


def _same(a: Controller, b: Controller) -> None:
    assert a.stats.levels == b.stats.levels
    np.testing.assert_array_equal(a._W, b._W)
    np.testing.assert_array_equal(a._planes, b._planes)


def _both(problem: SymbolicProblem, threads: int = 1) -> tuple[Controller, Controller]:
    tables, _ = problem.tables(use_cache=False)
    new = Synthesizer(tables, threads=threads, memo=False, use_cache=False).solve_problem(problem)
    old = Synthesizer(
        tables, threads=threads, memo=False, use_cache=False, kernel="frontier"
    ).solve_problem(problem)
    return new, old


@pytest.mark.parametrize("seed", [0, 1, 3])
def test_random_obstacles_give_the_frontier_kernels_words(seed: int) -> None:
    rng = np.random.default_rng(seed)
    budget = tiny.zero_budget() if seed == 0 else tiny.budget(0.5)
    problem = tiny.problem(
        budget, obstacles=_random_obstacles(rng, 3), grid=replace(tiny.GRID, npsi=12 + 6 * seed)
    )
    new, old = _both(problem)
    _same(new, old)
    assert new.stats.levels >= 2


def test_threads_give_the_same_words(problem: SymbolicProblem) -> None:
    new, old = _both(problem, threads=2)
    _same(new, old)
    assert new.stats.threads == 2


def test_wrapping_headings_and_two_words_per_row() -> None:
    # Heading offsets beyond npsi (padding rows that wrap more than once), ny = 70.
    grid = Grid(-1.5, -1.0, 0.1, 0.025, 20, 70, 8)
    axes = (np.array([0.0, 0.1]), np.array([-0.05, 0.0, 0.05]), np.array([-3.3, 0.0, 3.3]))
    problem = tiny.problem(
        tiny.zero_budget(),
        grid=grid,
        the_inputs=tiny.inputs(axes),
        obstacles=(Rect(-0.3, -0.1, 0.2, 0.4),),
        target=Rect(-1.0, -0.5, 0.45, 0.75),
    )
    new, old = _both(problem)
    _same(new, old)


def test_levels_one_at_a_time_hold_exactly_the_values_so_far(problem: SymbolicProblem) -> None:
    tables, _ = problem.tables(use_cache=False)
    synthesizer = Synthesizer(tables, memo=False)
    full = synthesizer.solve_problem(problem)
    flat = tables.hull_psi.reshape(-1, 2)
    free = problem.free_masks(flat[:, 0], flat[:, 1])
    target = problem.target_cells(problem.heading_free())
    obstacles = problem.inflated_obstacle_mask()
    solver = synthesizer.begin(free, target)
    finals = [full.layer_values(p) for p in range(tables.n_inputs)]
    assert solver.level == 0
    while True:
        snapshot = synthesizer.controller_of(solver, target, obstacles)
        assert snapshot.stats.levels == solver.level
        for p in range(tables.n_inputs):
            final = finals[p]
            expected = np.where(final <= solver.level, final, -1)
            np.testing.assert_array_equal(snapshot.layer_values(p), expected, err_msg=f"{p}")
        n = solver.advance()
        if n == 0:
            break
        assert n > 0
    assert solver.done
    assert solver.level == full.stats.levels
    assert solver.advance() == 0
    _same(synthesizer.controller_of(solver, target, obstacles), full)


def test_containment_is_checked_and_unknown_kernels_refused(problem: SymbolicProblem) -> None:
    tables, _ = problem.tables(use_cache=False)
    viable = np.zeros((3, tables.n_inputs, 2, 2, 1), dtype=np.uint64)
    assert nested_classes(tables.succ, tables.heading, viable)
    viable[1, 0, 0, 0, 0] = 1  # a class-1 viable bit outside class 0
    assert not nested_classes(tables.succ, tables.heading, viable)
    swapped = tables.succ[::-1].copy()
    if not np.array_equal(swapped, tables.succ):
        assert not nested_classes(swapped, tables.heading, viable[:, :, :0])
    with pytest.raises(GridError):
        Synthesizer(tables, kernel="dense")


def test_a_fixed_point_longer_than_the_planes_stops_at_their_last_level(
    problem: SymbolicProblem,
) -> None:
    # Two planes hold values up to 3: the solve stops there with exactly the states of
    # value <= 3, each with its final value (sound: the others are left out).
    tables, _ = problem.tables(use_cache=False)
    synthesizer = Synthesizer(tables, memo=False)
    full = synthesizer.solve_problem(problem)
    assert full.stats.levels > 3
    flat = tables.hull_psi.reshape(-1, 2)
    free = problem.free_masks(flat[:, 0], flat[:, 1])
    target = problem.target_cells(problem.heading_free())
    viable, goal = synthesizer._words(free, target, 1)
    axes = synthesizer.lattice.axes
    solver = LevelSolver(goal, viable, synthesizer._pads, tables.succ, tables.heading,
                         (len(axes[0]), len(axes[1]), len(axes[2])), n_planes=2)  # fmt: skip
    assert solver.solve() == -1
    assert solver.done
    assert solver.level == 3
    W, planes = solver.export()
    for p in range(0, tables.n_inputs, 5):
        final = full.layer_values(p)
        got = layer_values(W, planes, solver.pads, p, tables.grid.ny)
        np.testing.assert_array_equal(got, np.where(final <= 3, final, -1))
