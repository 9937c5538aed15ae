"""The fast solver against a plain-Python fixed point, the dense baseline and known answers."""

from __future__ import annotations

import math
import threading
from pathlib import Path

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
    build_tables,
    synthesize,
    tables_for,
)
from hil.controllers.symbolic.reference import dense_fixed_point
from hil.core.shapes import Rect
from hil.scenarios import Scenario

BoolArray = NDArray[np.bool_]


def brute_force(tables: Tables, obstacles: BoolArray, target: BoolArray) -> NDArray[np.int32]:
    """Explicit BFS fixed point over all cells and inputs, in plain Python."""
    g = tables.grid
    nx, ny, npsi = g.shape
    values = np.full((nx, ny, npsi), -1, dtype=np.int32)
    for i in range(nx):
        for j in range(ny):
            if target[i, j] and not obstacles[i, j]:
                values[i, j, :] = 0

    def tube_free(i: int, j: int, k: int, u: int) -> bool:
        for c in range(int(tables.tube_n[k, u])):
            ii = i + int(tables.tube_x0[k, u]) + c
            for jj in range(
                j + int(tables.tube_y[k, u, c, 0]), j + int(tables.tube_y[k, u, c, 1]) + 1
            ):
                if not (0 <= ii < nx and 0 <= jj < ny) or obstacles[ii, jj]:
                    return False
        return True

    def successors_win(i: int, j: int, k: int, u: int, level: int) -> bool:
        ox0, ox1, oy0, oy1 = (int(v) for v in tables.succ[k, u])
        for ii in range(i + ox0, i + ox1 + 1):
            for jj in range(j + oy0, j + oy1 + 1):
                if not (0 <= ii < nx and 0 <= jj < ny):
                    return False
                for ok in range(int(tables.heading[u, 0]), int(tables.heading[u, 1]) + 1):
                    v = values[ii, jj, (k + ok) % npsi]
                    if v < 0 or v > level:
                        return False
        return True

    level = 0
    while True:
        joined = [
            (i, j, k)
            for i in range(nx)
            for j in range(ny)
            for k in range(npsi)
            if values[i, j, k] < 0
            and not obstacles[i, j]
            and any(
                successors_win(i, j, k, u, level) and tube_free(i, j, k, u)
                for u in range(tables.n_inputs)
            )
        ]
        if not joined:
            return values
        level += 1
        for cell in joined:
            values[cell] = level


def _small_tables(nx: int, ny: int) -> Tables:
    grid = Grid(0.0, 0.0, 0.1, 0.1, nx, ny, 12)
    speeds = np.array(
        [[u, v, r] for u in (-0.05, 0.1) for v in (-0.05, 0.0, 0.05) for r in (-0.5, 0.0, 0.5)]
    )
    return build_tables(grid, speeds, 2.0)


@pytest.mark.parametrize(("nx", "ny"), [(8, 12), (5, 70)])  # one machine word and two
def test_fast_solver_equals_brute_force(nx: int, ny: int) -> None:
    tables = _small_tables(nx, ny)
    obstacles = np.zeros((nx, ny), dtype=bool)
    obstacles[nx - 3 : nx - 1, ny - 8 : ny - 5] = (
        True  # across the word boundary at j = 64 when ny = 70
    )
    obstacles[0, 3] = True
    obstacles[nx - 1, 1:4] = True
    target = np.zeros_like(obstacles)
    target[1:4, ny // 2 - 1 : ny // 2 + 1] = True
    expected = brute_force(tables, obstacles, target)
    for threads in (1, 2):
        got = Synthesizer(tables, threads=threads).solve(obstacles, target)
        np.testing.assert_array_equal(got.values, expected)
    assert expected.max() >= 5
    assert (expected < 0).sum() > nx * 12  # obstacles and some losing cells


def test_fast_solver_equals_brute_force_with_a_margin() -> None:
    grid = Grid(0.0, 0.0, 0.2, 0.2, 12, 10, 12)
    speeds = np.array(
        [[u, v, r] for u in (-0.1, 0.1, 0.2) for v in (-0.1, 0.0, 0.1) for r in (-0.2, 0.0, 0.2)]
    )
    tables = build_tables(grid, speeds, 2.0, np.full(3, 0.01))
    obstacles = np.zeros((12, 10), dtype=bool)
    obstacles[6:8, 5:10] = True
    target = np.zeros_like(obstacles)
    target[1:4, 6:9] = True
    expected = brute_force(tables, obstacles, target)
    np.testing.assert_array_equal(Synthesizer(tables).solve(obstacles, target).values, expected)
    assert expected.max() >= 5


def test_fast_solver_equals_dense_baseline() -> None:
    tables = _small_tables(6, 40)
    g = tables.grid
    obstacles = np.zeros((g.nx, g.ny), dtype=bool)
    obstacles[1:3, 20:22] = True
    target = np.zeros_like(obstacles)
    target[2:4, 2:5] = True
    values, iterations = dense_fixed_point(tables, obstacles, target)
    got = Synthesizer(tables).solve(obstacles, target)
    np.testing.assert_array_equal(got.values, values)
    assert got.stats.levels == iterations


def test_empty_arena_is_all_winning(coarse_problem: SymbolicProblem, coarse_tables: Tables) -> None:
    controller = Synthesizer(coarse_tables).solve_sets((), coarse_problem.target)
    assert controller.stats.winning_fraction == 1.0
    assert np.all(controller.values >= 0)


def test_wall_across_the_arena_makes_the_far_side_losing(
    coarse_problem: SymbolicProblem, coarse_tables: Tables
) -> None:
    wall = Rect(0.5, 1.0, -3.5, 3.5)
    controller = Synthesizer(coarse_tables).solve_sets((wall,), coarse_problem.target)
    g = coarse_problem.grid
    x_left = g.x_min_m + (np.arange(g.nx) + 1) * g.cell_x_m
    x_right = g.x_min_m + np.arange(g.nx) * g.cell_x_m
    far = x_right > wall.x_max_m
    near = x_left < wall.x_min_m
    assert np.all(controller.values[far] == -1)
    assert np.all(controller.values[near][~controller.obstacles[near]] >= 0)
    assert controller.value((3.0, 0.0, 0.0)) == math.inf
    assert controller.safe_inputs((3.0, 0.0, 0.0)).shape == (0, 3)


def test_target_alone_has_value_zero(
    coarse_problem: SymbolicProblem, coarse_controller: Controller
) -> None:
    target = coarse_problem.target_mask()
    v = coarse_controller.values
    assert np.all(v[target] == 0)
    assert np.all(v[~target] != 0)
    assert coarse_controller.value((-2.75, 1.5, 0.3)) == 0.0
    assert coarse_controller.safe_inputs((-2.75, 1.5, 0.3)).shape == (0, 3)


def test_values_are_bfs_levels(coarse_controller: Controller) -> None:
    v = coarse_controller.values
    levels = np.unique(v[v >= 0])
    np.testing.assert_array_equal(levels, np.arange(levels.max() + 1))
    assert coarse_controller.stats.levels == levels.max()


def test_no_winning_cell_is_reported(
    coarse_problem: SymbolicProblem, coarse_tables: Tables
) -> None:
    cover = Rect(-3.5, -1.5, 0.0, 3.0)  # over the whole target
    controller = Synthesizer(coarse_tables).solve_sets((cover,), coarse_problem.target)
    assert not controller.has_winning_start
    assert controller.stats.winning_cells == 0
    assert controller.stats.winning_fraction == 0.0
    assert controller.safe_inputs((3.0, 2.0, 0.0)).shape == (0, 3)
    with pytest.raises(
        NoWinningSetError, match="no winning cell outside the target: 0 target cells"
    ):
        Synthesizer(coarse_tables).solve_sets((cover,), coarse_problem.target, require_winning=True)


def test_resynthesis_reuses_tables_and_runs_in_a_thread(
    coarse: Scenario,
    coarse_problem: SymbolicProblem,
    coarse_tables: Tables,
    coarse_controller: Controller,
) -> None:
    moved = SymbolicProblem.from_scenario(
        coarse.with_obstacles_moved(np.array([[0.4, 0.0], [-0.2, 0.0]]))
    )
    synthesizer = Synthesizer(coarse_tables)
    results: list[Controller] = []
    worker = threading.Thread(
        target=lambda: results.append(synthesizer.solve_sets(moved.obstacles, moved.target))
    )
    worker.start()
    while worker.is_alive():  # the lookup keeps working meanwhile
        coarse_controller.safe_inputs((3.0, -1.0, 2.0))
        worker.join(0.001)
    assert len(results) == 1
    assert results[0].tables is coarse_tables
    again = synthesize(moved, tables=coarse_tables, threads=1)
    np.testing.assert_array_equal(results[0].values, again.values)
    assert not np.array_equal(results[0].values, coarse_controller.values)


def test_tables_for_another_problem_are_refused(
    coarse_problem: SymbolicProblem, coarse_tables: Tables
) -> None:
    other = SymbolicProblem(
        coarse_problem.grid,
        coarse_problem.inputs,
        1.0,
        coarse_problem.margin,
        coarse_problem.obstacles,
        coarse_problem.target,
    )
    with pytest.raises(GridError, match="another grid"):
        synthesize(other, tables=coarse_tables)


def test_masks_of_the_wrong_shape_are_refused(coarse_tables: Tables) -> None:
    with pytest.raises(GridError, match="masks must have shape"):
        Synthesizer(coarse_tables).solve(np.zeros((3, 3), dtype=bool), np.zeros((3, 3), dtype=bool))
    with pytest.raises(GridError, match="threads"):
        Synthesizer(coarse_tables, threads=0)


def test_tables_are_cached_on_disk(coarse_problem: SymbolicProblem, tmp_path: Path) -> None:
    p = coarse_problem
    first, cached_first = tables_for(p.grid, p.inputs, p.tau_s, p.margin, cache_dir=tmp_path)
    second, cached_second = tables_for(p.grid, p.inputs, p.tau_s, p.margin, cache_dir=tmp_path)
    assert (cached_first, cached_second) == (False, True)
    np.testing.assert_array_equal(first.succ, second.succ)
    np.testing.assert_array_equal(first.tube_y, second.tube_y)
    # A corrupt entry is rebuilt, not trusted.
    (entry,) = tmp_path.glob("tables-*.npz")
    entry.write_bytes(b"garbage")
    third, cached_third = tables_for(p.grid, p.inputs, p.tau_s, p.margin, cache_dir=tmp_path)
    assert not cached_third
    np.testing.assert_array_equal(first.succ, third.succ)


def test_fast_solver_equals_brute_force_when_turning_past_a_full_circle() -> None:
    # A yaw rate of 3.3 rad/s turns 6.6 rad in tau: heading offsets 8 and 9 on a grid of
    # 8 heading cells, so the solver reads padding rows that wrap more than once.
    grid = Grid(0.0, 0.0, 0.1, 0.1, 7, 8, 8)
    straight = [[u, v, 0.0] for u in (-0.05, 0.1) for v in (-0.05, 0.0, 0.05)]
    speeds = np.array([*straight, [0.1, 0.0, -3.3], [0.1, 0.0, 3.3]])
    tables = build_tables(grid, speeds, 2.0)
    assert tables.heading.max() > grid.npsi
    obstacles = np.zeros((7, 8), dtype=bool)
    obstacles[4, 2:6] = True
    target = np.zeros_like(obstacles)
    target[1:3, 3:5] = True
    expected = brute_force(tables, obstacles, target)
    assert expected.max() >= 1
    for threads in (1, 2):
        got = Synthesizer(tables, threads=threads).solve(obstacles, target)
        np.testing.assert_array_equal(got.values, expected)
