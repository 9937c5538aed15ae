"""The offset tables: closed-form displacement, containment of sampled motion per class,
growth with the budget, the class order and late ticks, heading offsets, the disk cache.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.symbolic import (
    Grid,
    GridError,
    SymbolicProblem,
    Tables,
    build_tables,
    synthesize,
    tables_for,
)
from hil.controllers.symbolic.abstraction import N_CLASSES, displacement
from hil.core.transient import TransientBudget
from tests.controllers.symbolic import tiny

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

GRID = Grid(0.0, 0.0, 0.05, 0.05, 10, 10, 60)
INPUTS = np.array(
    [[u, v, r] for u in (-0.1, 0.05, 0.2) for v in (-0.1, 0.0, 0.1) for r in (-0.2, 0.0, 0.2)]
)
TAU = 2.0


def test_displacement_matches_numerical_integration() -> None:
    inputs = np.array([[0.2, 0.1, 0.2], [-0.1, 0.05, -0.1], [0.15, 0.0, 0.0], [0.0, 0.0, 0.2]])
    t = np.array([0.0, 0.7, 2.0])
    got = displacement(inputs, t)
    fine = np.linspace(0.0, 2.0, 200001)
    for n, (u, v, r) in enumerate(inputs):
        psi = r * fine
        vx = u * np.cos(psi) - v * np.sin(psi)
        vy = u * np.sin(psi) + v * np.cos(psi)
        for m, tm in enumerate(t):
            mask = fine <= tm + 1e-12
            x = np.trapezoid(vx[mask], fine[mask])
            y = np.trapezoid(vy[mask], fine[mask])
            np.testing.assert_allclose(got[n, m], [x, y], atol=1e-9)


@pytest.fixture(scope="module")
def zero_tables() -> Tables:
    return build_tables(GRID, INPUTS, TAU, TransientBudget.zero(TAU), late_s=0.2)


@pytest.fixture(scope="module")
def budget_tables() -> Tables:
    return build_tables(GRID, INPUTS, TAU, tiny.budget(), late_s=0.2)


def _check_contains(
    tables: Tables,
    c: int,
    k: int,
    u: int,
    path: FloatArray,
    ends: FloatArray,
    end_heading_cells: IntArray,
) -> None:
    """Assert that poses (n, T, 2) lie in the tube and ends (n, E, 2) in the successor box.

    All relative to cell (0, 0, k); end_heading_cells (n, E) are unwrapped cell indices.
    """
    g = tables.grid
    ox = np.floor(ends[..., 0] / g.cell_x_m).astype(int)
    oy = np.floor(ends[..., 1] / g.cell_y_m).astype(int)
    ox0, ox1, oy0, oy1 = tables.succ[c, k, u]
    assert np.all((ox >= ox0) & (ox <= ox1)), (c, k, u, ox.min(), ox.max(), ox0, ox1)
    assert np.all((oy >= oy0) & (oy <= oy1)), (c, k, u, oy.min(), oy.max(), oy0, oy1)
    ok = end_heading_cells - k
    h0, h1 = tables.heading[c, u]
    assert np.all((ok >= h0) & (ok <= h1)), (c, k, u, ok.min(), ok.max(), h0, h1)
    px = np.floor(path[..., 0] / g.cell_x_m).astype(int).ravel()
    py = np.floor(path[..., 1] / g.cell_y_m).astype(int).ravel()
    col = px - tables.tube_x0[c, k, u]
    assert np.all((col >= 0) & (col < tables.tube_n[c, k, u])), (c, k, u)
    assert np.all(py >= tables.tube_y[c, k, u, col, 0]), (c, k, u)
    assert np.all(py <= tables.tube_y[c, k, u, col, 1]), (c, k, u)


K_SAMPLES = (0, 14, 15, 29, 30, 44, 45, 59)  # the axes' cells and both ends (wrap)


def test_exact_motion_stays_in_the_boxes_of_every_class(zero_tables: Tables) -> None:
    # Zero budget: the exact arcs from every point of the cell, at every end time in
    # [tau, tau + late], lie in the successor box; the whole path in the tube.
    t = zero_tables
    g = t.grid
    rng = np.random.default_rng(5)
    times = np.linspace(0.0, t.tau_s + t.late_s, 461)
    ends = times >= t.tau_s - 1e-12
    hp = g.heading_cell_rad
    for k in K_SAMPLES:
        start = tiny.points_in_cell(g, (0, 0, k), 150, rng)
        for u in range(t.n_inputs):
            path = tiny.flow(start, np.repeat(t.inputs[u : u + 1], len(start), axis=0), times)
            k_end = np.floor((path[:, ends, 2] + math.pi) / hp).astype(np.int64)
            for c in range(N_CLASSES):
                _check_contains(t, c, k, u, path[..., :2], path[:, ends, :2], k_end)


def _perturbed(
    start: FloatArray,
    nu: FloatArray,
    env: FloatArray,
    bin_s: float,
    horizon: float,
    rng: np.random.Generator,
) -> tuple[FloatArray, FloatArray]:
    """Fly nu + e, e piecewise constant within env (n_bins, 3) per bin; return (times, poses).

    Half the flights keep one sign per axis throughout (the worst drift), half redraw it
    every half bin.
    """
    n = len(start)
    dt = bin_s / 20
    steps = round(horizon / dt)
    times: FloatArray = dt * np.arange(steps + 1, dtype=np.float64)
    out: FloatArray = np.empty((n, steps + 1, 3))
    out[:, 0] = start
    signs = rng.choice([-1.0, 1.0], size=(n, 3))
    scale = rng.uniform(0.8, 1.0, size=(n, 3))
    for s in range(steps):
        if s % 10 == 0:
            redraw = rng.choice([-1.0, 1.0], size=(n, 3))
            signs[n // 2 :] = redraw[n // 2 :]
        b = min(int((s * dt + 1e-12) / bin_s), env.shape[0] - 1)
        e = signs * scale * env[b]
        out[:, s + 1] = tiny.flow(out[:, s], nu + e, np.array([dt]))[:, 0]
    return times, out


def test_budgeted_motion_stays_in_the_boxes_of_its_class(budget_tables: Tables) -> None:
    # Velocity errors within the class's envelope, a true start within the estimation
    # bound of the cell, and an estimate of the end within the bound: the estimated end
    # lies in the successor box, the true path in the tube. Class 2 uses the change
    # envelope (the budget has no class of its own for first commands).
    t = budget_tables
    g = t.grid
    b = tiny.budget()
    eps, eps_psi = b.estimation_position_m, b.estimation_heading_rad
    rng = np.random.default_rng(8)
    hp = g.heading_cell_rad
    n = 40
    m = t.n_inputs
    for k in (0, 15, 29, 59):
        for c in range(N_CLASSES):
            start = tiny.points_in_cell(g, (0, 0, k), n * m, rng)
            start[:, :2] += rng.uniform(-eps, eps, (len(start), 2)) / math.sqrt(2.0)
            start[:, 2] += rng.uniform(-eps_psi, eps_psi, len(start))
            nu = np.repeat(t.inputs, n, axis=0)  # rows u n .. u n + n - 1 fly input u
            env = b.envelopes[min(c, 1)]
            times, path = _perturbed(start, nu, env, b.bin_s, t.tau_s + t.late_s, rng)
            seen = path[:, times >= t.tau_s - 1e-12].copy()
            seen[..., :2] += rng.uniform(-eps, eps, seen[..., :2].shape) / math.sqrt(2.0)
            seen[..., 2] += rng.uniform(-eps_psi, eps_psi, seen[..., 2].shape)
            k_end = np.floor((seen[..., 2] + math.pi) / hp).astype(np.int64)
            for u in range(m):
                rows = slice(u * n, (u + 1) * n)
                _check_contains(t, c, k, u, path[rows, :, :2], seen[rows, :, :2], k_end[rows])


def _tube_set(t: Tables, c: int, k: int, u: int) -> set[tuple[int, int]]:
    return set(tiny.tube_cells(t, c, k, u))


def _assert_contains(big: Tables, cb: int, small: Tables, cs: int, tubes: bool = True) -> None:
    """Assert every box of class cs of `small` lies in class cb's of `big` (tubes too)."""
    assert np.all(big.succ[cb][..., [0, 2]] <= small.succ[cs][..., [0, 2]])
    assert np.all(big.succ[cb][..., [1, 3]] >= small.succ[cs][..., [1, 3]])
    assert np.all(big.heading[cb][:, 0] <= small.heading[cs][:, 0])
    assert np.all(big.heading[cb][:, 1] >= small.heading[cs][:, 1])
    assert np.all(big.hull_psi[cb][..., 0] <= small.hull_psi[cs][..., 0])
    assert np.all(big.hull_psi[cb][..., 1] >= small.hull_psi[cs][..., 1])
    for k in range(0, big.grid.npsi, 7) if tubes else ():
        for u in range(big.n_inputs):
            assert _tube_set(small, cs, k, u) <= _tube_set(big, cb, k, u), (cb, cs, k, u)


def test_a_larger_budget_only_grows_the_boxes(zero_tables: Tables, budget_tables: Tables) -> None:
    larger = build_tables(GRID, INPUTS, TAU, tiny.budget(2.0), late_s=0.2)
    for small, big in ((zero_tables, budget_tables), (budget_tables, larger)):
        for c in range(N_CLASSES):
            _assert_contains(big, c, small, c)
        assert big.key != small.key
        assert big.budget_key != small.budget_key
    # ... and strictly somewhere: the budget is not ignored.
    assert np.any(larger.succ[1, ..., 1] > budget_tables.succ[1, ..., 1])
    assert np.any(budget_tables.succ[0, ..., 1] > zero_tables.succ[0, ..., 1])
    # The zero budget makes the classes one.
    for c in (1, 2):
        np.testing.assert_array_equal(zero_tables.succ[c], zero_tables.succ[0])
        np.testing.assert_array_equal(zero_tables.tube_y[c], zero_tables.tube_y[0])


def test_classes_are_ordered(budget_tables: Tables) -> None:
    t = budget_tables
    _assert_contains(t, 1, t, 0)
    _assert_contains(t, 2, t, 1)
    assert np.any(t.succ[1, ..., 1] > t.succ[0, ..., 1])  # a change costs more than a hold


def test_the_estimation_bound_alone_grows_the_boxes(zero_tables: Tables) -> None:
    estimate_only = tiny.envelope_budget(np.zeros((3, 9, 3)), 0.02, 0.02)
    t = build_tables(GRID, INPUTS, TAU, estimate_only, late_s=0.2)
    for c in range(N_CLASSES):
        _assert_contains(t, c, zero_tables, c)
    assert np.any(t.heading[..., 1] > zero_tables.heading[..., 1])
    assert np.any(t.succ[..., 1] > zero_tables.succ[..., 1])


def test_boxes_are_tight() -> None:
    # Straight ahead at 0.2 m/s for 2 s from heading cell [0, 6 deg): dx in [0.4 cos 6 deg,
    # 0.4] = [0.398, 0.4] m, so from x in [0, 0.05) the end lies in [0.398, 0.45): cells
    # 7 and 8; dy in [0, 0.042] m: cells 0 and 1. The tube covers x cells 0 .. 8.
    t = build_tables(GRID, INPUTS, TAU, TransientBudget.zero(TAU))
    u = int(np.flatnonzero((t.inputs == [0.2, 0.0, 0.0]).all(axis=1))[0])
    for c in range(N_CLASSES):
        np.testing.assert_array_equal(t.succ[c, 30, u], [7, 8, 0, 1])
        np.testing.assert_array_equal(t.heading[c, u], [0, 0])
        assert t.tube_x0[c, 30, u] == 0
        assert t.tube_n[c, 30, u] == 9
    # Standing still: the cell itself, at any heading cell.
    still = build_tables(GRID, np.zeros((1, 3)), TAU, TransientBudget.zero(TAU))
    assert np.all(still.succ[..., [0, 2]] == 0)
    assert np.all(still.succ[..., [1, 3]] == 0)
    assert np.all(still.heading == 0)
    assert np.all(still.tube_n == 1)
    assert np.all(still.tube_y[..., 0, :] == 0)


def test_heading_offsets_wrap_and_round() -> None:
    zero = TransientBudget.zero(TAU)
    # r tau = 0.4 rad = 3.82 heading cells of 6 deg: the cell lands on offsets 3 and 4.
    t = build_tables(GRID, INPUTS, TAU, zero)
    for u, r in enumerate(t.inputs[:, 2]):
        expected = {0.2: [3, 4], 0.0: [0, 0], -0.2: [-4, -3]}[round(float(r), 1)]
        for c in range(N_CLASSES):
            np.testing.assert_array_equal(t.heading[c, u], expected)
    # A turn of exactly one cell (pi/6 on 12 cells) moves the cell onto one cell, not two,
    # whatever the rounding of r tau.
    grid12 = Grid(0.0, 0.0, 0.1, 0.1, 4, 4, 12)
    r = math.pi / 12 / TAU * 2  # r tau = pi / 6
    exact = np.array([[0.0, 0.0, r], [0.0, 0.0, -r], [0.0, 0.0, 7 * r]])
    t12 = build_tables(grid12, exact, TAU, zero)
    np.testing.assert_array_equal(t12.heading[:, 0], [[1, 1]] * 3)
    np.testing.assert_array_equal(t12.heading[:, 1], [[-1, -1]] * 3)
    np.testing.assert_array_equal(t12.heading[:, 2], [[7, 7]] * 3)
    # Turning past a full circle: 3.3 rad/s for 2 s = 6.6 rad = 8.4 cells of 45 deg.
    grid8 = Grid(0.0, 0.0, 0.1, 0.1, 4, 4, 8)
    t8 = build_tables(grid8, np.array([[0.0, 0.0, 3.3], [0.0, 0.0, -3.3]]), TAU, zero)
    np.testing.assert_array_equal(t8.heading[0], [[8, 9], [-9, -8]])
    # With an estimate error the offsets widen by at most 2 eps / cell width each way.
    eps = tiny.envelope_budget(np.zeros((3, 9, 3)), 0.0, 0.01)
    t12e = build_tables(grid12, exact, TAU, eps)
    np.testing.assert_array_equal(t12e.heading[:, 0], [[0, 2]] * 3)


def test_late_ticks_grow_the_successor() -> None:
    zero = TransientBudget.zero(TAU, n_bins=10)  # 2.5 s: covers the half-second late
    on_time = build_tables(GRID, INPUTS, TAU, zero, late_s=0.0)
    late = build_tables(GRID, INPUTS, TAU, zero, late_s=0.5)
    for c in range(N_CLASSES):
        # Tubes sampled over other horizons need not nest (their padding differs); each
        # holds the motion over its own horizon (the containment tests above).
        _assert_contains(late, c, on_time, c, tubes=False)
    assert late.key != on_time.key
    assert np.all(late.tube_x0 + late.tube_n >= on_time.tube_x0 + on_time.tube_n - 1)
    # 0.2 m/s straight ahead from heading cell 30 over [2.0, 2.5] s: the end moves by
    # [0.398, 0.5] m, so from x in [0, 0.05) it lies in cells 7 .. 10 (on time: 7 .. 8),
    # y in cells 0 .. 1; the tube covers x cells 0 .. 10. The padding between time
    # samples may add a cell on each side, no more.
    u = int(np.flatnonzero((INPUTS == [0.2, 0.0, 0.0]).all(axis=1))[0])
    ox0, ox1, oy0, oy1 = (int(v) for v in late.succ[0, 30, u])
    assert (ox0, oy0) in {(7, 0), (7, -1), (6, 0), (6, -1)}
    assert ox1 in (10, 11)
    assert oy1 in (1, 2)
    assert late.tube_x0[0, 30, u] in (0, -1)
    assert late.tube_x0[0, 30, u] + late.tube_n[0, 30, u] - 1 in (10, 11)
    # Turning 0.2 rad/s over [2.0, 2.5] s: 0.4 .. 0.5 rad = 3.82 .. 4.77 cells.
    r_pos = int(np.flatnonzero((INPUTS == [0.2, 0.0, 0.2]).all(axis=1))[0])
    np.testing.assert_array_equal(late.heading[0, r_pos], [3, 5])


@pytest.mark.parametrize(
    ("inputs", "tau", "late", "match"),
    [
        (np.zeros((3, 2)), TAU, 0.0, "inputs"),
        (np.zeros((0, 3)), TAU, 0.0, "inputs"),
        (np.zeros(3), TAU, 0.0, "inputs"),
        (np.array([[0.1, 0.0, math.nan]]), TAU, 0.0, "inputs"),
        (np.array([[math.inf, 0.0, 0.0]]), TAU, 0.0, "inputs"),
        (INPUTS, 0.0, 0.0, "tau_s"),
        (INPUTS, -1.0, 0.0, "tau_s"),
        (INPUTS, math.nan, 0.0, "tau_s"),
        (INPUTS, math.inf, 0.0, "tau_s"),
        (INPUTS, TAU, -0.1, "late_s"),
        (INPUTS, TAU, math.nan, "late_s"),
        (INPUTS, TAU, math.inf, "late_s"),
    ],
)
def test_bad_arguments_are_refused(
    inputs: FloatArray, tau: float, late: float, match: str, tmp_path: Path
) -> None:
    zero = TransientBudget.zero(TAU)
    with pytest.raises(GridError, match=match):
        build_tables(GRID, inputs, tau, zero, late)
    with pytest.raises(GridError, match=match):
        tables_for(GRID, inputs, tau, zero, late, cache_dir=tmp_path)
    assert not any(tmp_path.iterdir())


def test_tables_are_cached_on_disk(tmp_path: Path) -> None:
    b = tiny.budget()
    first, cached_first = tables_for(GRID, INPUTS, TAU, b, 0.1, cache_dir=tmp_path)
    second, cached_second = tables_for(GRID, INPUTS, TAU, b, 0.1, cache_dir=tmp_path)
    assert (cached_first, cached_second) == (False, True)
    fields = ("succ", "heading", "tube_x0", "tube_n", "tube_y", "hull_psi", "yaw_index")
    for name in fields:
        np.testing.assert_array_equal(getattr(first, name), getattr(second, name), err_msg=name)
    assert (second.key, second.budget_key, second.late_s) == (first.key, first.budget_key, 0.1)
    # Another budget or late allowance is another entry, not the cached one.
    _, cached_other = tables_for(GRID, INPUTS, TAU, tiny.budget(2.0), 0.1, cache_dir=tmp_path)
    _, cached_late = tables_for(GRID, INPUTS, TAU, b, 0.2, cache_dir=tmp_path)
    assert not cached_other
    assert not cached_late
    assert len(list(tmp_path.glob("tables-*.npz"))) == 3
    # A corrupt entry is rebuilt, not trusted; so is one holding another key.
    entry = tmp_path / f"tables-{first.key}.npz"
    late_key = tables_for(GRID, INPUTS, TAU, b, 0.2, cache_dir=tmp_path)[0].key
    for bad in (b"garbage", (tmp_path / f"tables-{late_key}.npz").read_bytes()):
        entry.write_bytes(bad)
        again, cached_again = tables_for(GRID, INPUTS, TAU, b, 0.1, cache_dir=tmp_path)
        assert not cached_again
        for name in fields:
            np.testing.assert_array_equal(getattr(first, name), getattr(again, name))
        assert tables_for(GRID, INPUTS, TAU, b, 0.1, cache_dir=tmp_path)[1]  # rewritten
    # use_cache=False reads and writes nothing.
    fresh = tmp_path / "fresh"
    _, cached_fresh = tables_for(GRID, INPUTS, TAU, b, 0.1, cache_dir=fresh, use_cache=False)
    assert not cached_fresh
    assert not fresh.exists()


def test_synthesize_refuses_tables_of_another_problem() -> None:
    small = tiny.problem(obstacles=())
    tables, _ = small.tables(use_cache=False)
    others: list[SymbolicProblem] = [
        replace(small, budget=tiny.budget(2.0)),
        replace(small, late_s=0.2),
        replace(small, tau_s=1.0),
        replace(small, inputs=small.inputs[:9]),
        replace(small, inputs=small.inputs + 0.001),
        replace(small, grid=replace(small.grid, npsi=8)),
    ]
    for other in others:
        with pytest.raises(GridError, match="another grid"):
            synthesize(other, tables=tables)
    # The same budget under another source text is the same numbers: accepted.
    renamed = replace(small, budget=replace(tiny.budget(), source="elsewhere"))
    assert synthesize(renamed, tables=tables).tables is tables
