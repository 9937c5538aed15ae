"""The offset tables: closed-form displacement, arc boxes and sampled containment."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.controllers.symbolic import Grid, GridError, Tables, build_tables
from hil.controllers.symbolic.abstraction import displacement


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


def _sampled_offsets(
    tables: Tables, k: int, u: int, rng: np.random.Generator, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """Fly input u from n random points of cell (0, 0, k); return final offsets and path cells."""
    g = tables.grid
    x0 = rng.random(n) * g.cell_x_m
    y0 = rng.random(n) * g.cell_y_m
    psi0 = -math.pi + (k + rng.random(n)) * g.heading_cell_rad
    t = np.linspace(0.0, tables.tau_s, 401)
    d = displacement(tables.inputs[u : u + 1], t)[0]  # (T, 2)
    c, s = np.cos(psi0)[:, None], np.sin(psi0)[:, None]
    x = x0[:, None] + c * d[None, :, 0] - s * d[None, :, 1]
    y = y0[:, None] + s * d[None, :, 0] + c * d[None, :, 1]
    psi = psi0 + tables.inputs[u, 2] * tables.tau_s
    ox = np.floor(x / g.cell_x_m).astype(int)
    oy = np.floor(y / g.cell_y_m).astype(int)
    ok = np.floor((psi + math.pi) / g.heading_cell_rad).astype(int) - k
    final = np.stack([ox[:, -1], oy[:, -1], ok], axis=1)
    return final, np.stack([ox.ravel(), oy.ravel()], axis=1)


@pytest.fixture(scope="module")
def tables() -> Tables:
    grid = Grid(0.0, 0.0, 0.05, 0.05, 10, 10, 60)
    inputs = np.array(
        [[u, v, r] for u in (-0.1, 0.05, 0.2) for v in (-0.1, 0.0, 0.1) for r in (-0.2, 0.0, 0.2)]
    )
    return build_tables(grid, inputs, 2.0)


def test_sampled_motion_stays_in_the_boxes(tables: Tables) -> None:
    rng = np.random.default_rng(5)
    for k in (0, 14, 15, 29, 44, 45, 59):
        for u in range(tables.n_inputs):
            final, path = _sampled_offsets(tables, k, u, rng, 300)
            ox0, ox1, oy0, oy1 = tables.succ[k, u]
            assert np.all((final[:, 0] >= ox0) & (final[:, 0] <= ox1)), (k, u)
            assert np.all((final[:, 1] >= oy0) & (final[:, 1] <= oy1)), (k, u)
            assert np.all(
                (final[:, 2] >= tables.heading[u, 0]) & (final[:, 2] <= tables.heading[u, 1])
            ), (k, u)
            col = path[:, 0] - tables.tube_x0[k, u]
            assert np.all((col >= 0) & (col < tables.tube_n[k, u])), (k, u)
            assert np.all(path[:, 1] >= tables.tube_y[k, u, col, 0]), (k, u)
            assert np.all(path[:, 1] <= tables.tube_y[k, u, col, 1]), (k, u)


def test_boxes_are_tight(tables: Tables) -> None:
    # Straight ahead at 0.2 m/s for 2 s from heading cell [0, 6 deg): dx in [0.4 cos 6 deg, 0.4]
    # = [0.398, 0.4] m, so from x in [0, 0.05) the end lies in [0.398, 0.45): cells 7 and 8;
    # dy in [0, 0.042] m: cells 0 and 1. The tube covers x cells 0 .. 8.
    u = int(np.flatnonzero((tables.inputs == [0.2, 0.0, 0.0]).all(axis=1))[0])
    np.testing.assert_array_equal(tables.succ[30, u], [7, 8, 0, 1])
    np.testing.assert_array_equal(tables.heading[u], [0, 0])
    assert tables.tube_x0[30, u] == 0
    assert tables.tube_n[30, u] == 9


def test_heading_offsets_wrap_and_round(tables: Tables) -> None:
    # r tau = 0.4 rad = 3.82 heading cells of 6 deg: the cell lands on offsets 3 and 4.
    for u, r in enumerate(tables.inputs[:, 2]):
        expected = {0.2: [3, 4], 0.0: [0, 0], -0.2: [-4, -3]}[round(float(r), 1)]
        np.testing.assert_array_equal(tables.heading[u], expected)


def test_margin_only_grows_the_boxes(tables: Tables) -> None:
    robust = build_tables(tables.grid, tables.inputs, tables.tau_s, np.array([0.01, 0.01, 0.01]))
    assert np.all(robust.succ[..., [0, 2]] <= tables.succ[..., [0, 2]])
    assert np.all(robust.succ[..., [1, 3]] >= tables.succ[..., [1, 3]])
    assert np.all(robust.heading[:, 0] <= tables.heading[:, 0])
    assert np.all(robust.heading[:, 1] >= tables.heading[:, 1])
    assert robust.key != tables.key


def test_bad_arguments_are_refused(tables: Tables) -> None:
    with pytest.raises(GridError, match="inputs"):
        build_tables(tables.grid, np.zeros((3, 2)), 2.0)
    with pytest.raises(GridError, match="tau_s"):
        build_tables(tables.grid, tables.inputs, 0.0)
    with pytest.raises(GridError, match="margin"):
        build_tables(tables.grid, tables.inputs, 2.0, np.array([-0.1, 0.0, 0.0]))
