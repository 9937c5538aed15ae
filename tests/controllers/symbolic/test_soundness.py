"""An independent check of the guarantee, by simulation (not the controller's tables).

For random winning states of the coarse scenario, every safe input is flown with the
exact kinematic flow, sampled finely over [0, tau], from random points of the state's
cell; the path must stay in the arena, never touch an inflated obstacle (the shapes,
not their cells), and end in a cell of strictly smaller value. With a margin, the body
velocity is perturbed by random piecewise-constant errors within the margin.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.symbolic import Controller, SymbolicProblem, synthesize
from hil.core.shapes import Rect
from hil.scenarios import Scenario, TrackingMargin

FloatArray = NDArray[np.float64]

N_STATES = 2000
N_POINTS = 3  # random points per cell and input
N_STEPS = 200  # time steps over [0, tau]


def _flow(start: FloatArray, nu: FloatArray, t: FloatArray) -> FloatArray:
    """Exact pose after holding nu for times t: start (n, 3), nu (n, 3), t (T,) -> (n, T, 3)."""
    x0, y0, psi0 = (start[:, c : c + 1] for c in range(3))
    u, v, r = (nu[:, c : c + 1] for c in range(3))
    tt = t[None, :]
    psi = psi0 + r * tt
    straight = np.abs(r) < 1e-12
    r_safe = np.where(straight, 1.0, r)
    # Integrate R(psi0 + r s) (u, v) ds in closed form (independent of the abstraction's code).
    sin_d = np.sin(psi) - np.sin(psi0)
    cos_d = np.cos(psi) - np.cos(psi0)
    x_curved = (u * sin_d + v * cos_d) / r_safe
    y_curved = (-u * cos_d + v * sin_d) / r_safe
    x_line = (u * np.cos(psi0) - v * np.sin(psi0)) * tt
    y_line = (u * np.sin(psi0) + v * np.cos(psi0)) * tt
    x = x0 + np.where(straight, x_line, x_curved)
    y = y0 + np.where(straight, y_line, y_curved)
    return np.stack([x, y, np.broadcast_to(psi, x.shape)], axis=-1)


def _quantize(problem: SymbolicProblem, pose: FloatArray) -> tuple[NDArray[np.int64], ...]:
    g = problem.grid
    i = np.floor((pose[..., 0] - g.x_min_m) / g.cell_x_m).astype(np.int64)
    j = np.floor((pose[..., 1] - g.y_min_m) / g.cell_y_m).astype(np.int64)
    psi = np.mod(pose[..., 2] + math.pi, 2 * math.pi)
    k = np.minimum(np.floor(psi / (2 * math.pi / g.npsi)).astype(np.int64), g.npsi - 1)
    return i, j, k


def _violations(
    problem: SymbolicProblem, controller: Controller, path: FloatArray, v_start: NDArray[np.int64]
) -> dict[str, int]:
    """Count paths (n, T, 3) that leave the arena, touch an obstacle, or do not descend."""
    g = problem.grid
    x, y = path[..., 0], path[..., 1]
    outside = (x < g.x_min_m) | (x >= g.x_max_m) | (y < g.y_min_m) | (y >= g.y_max_m)
    hit = np.zeros(x.shape, dtype=bool)
    for shape in problem.obstacles:
        assert isinstance(shape, Rect)
        hit |= (
            (x >= shape.x_min_m)
            & (x <= shape.x_max_m)
            & (y >= shape.y_min_m)
            & (y <= shape.y_max_m)
        )
    i, j, k = _quantize(problem, path[:, -1, :])
    ok_cell = (i >= 0) & (i < g.nx) & (j >= 0) & (j < g.ny)
    v_end = np.full(i.shape, -1, dtype=np.int64)
    v_end[ok_cell] = controller.values[i[ok_cell], j[ok_cell], k[ok_cell]]
    no_descent = (v_end < 0) | (v_end >= v_start)
    return {
        "left_arena": int(outside.any(axis=1).sum()),
        "touched_obstacle": int(hit.any(axis=1).sum()),
        "no_descent": int(no_descent.sum()),
    }


def _check(
    problem: SymbolicProblem, controller: Controller, rng: np.random.Generator, margin: FloatArray
) -> tuple[dict[str, int], int]:
    g = problem.grid
    values = controller.values
    cells = np.argwhere(values > 0)
    # Bias a quarter of the picks to the heading cells that wrap (first and last).
    picks = cells[rng.integers(0, len(cells), N_STATES)]
    wrap = np.argwhere((values > 0) & np.isin(np.arange(g.npsi), [0, g.npsi - 1])[None, None, :])
    picks[: N_STATES // 4] = wrap[rng.integers(0, len(wrap), N_STATES // 4)]
    t = np.linspace(0.0, problem.tau_s, N_STEPS + 1)
    totals = {"left_arena": 0, "touched_obstacle": 0, "no_descent": 0}
    flights = 0
    for i, j, k in picks:
        lo = g.cell_bounds(int(i), int(j), int(k))
        idx = controller.safe_input_indices_at((int(i), int(j), int(k)))
        assert idx.size > 0, "a winning cell outside the target has no safe input"
        nu = np.repeat(controller.inputs[idx], N_POINTS, axis=0)
        start = lo[0] + rng.random((len(nu), 3)) * (lo[1] - lo[0])
        if np.any(margin > 0.0):
            path = _perturbed_flight(start, nu, t, margin, rng)
        else:
            path = _flow(start, nu, t)
        v_start = np.full(len(nu), values[i, j, k], dtype=np.int64)
        for key, count in _violations(problem, controller, path, v_start).items():
            totals[key] += count
        flights += len(nu)
    return totals, flights


def _perturbed_flight(
    start: FloatArray, nu: FloatArray, t: FloatArray, margin: FloatArray, rng: np.random.Generator
) -> FloatArray:
    """Fly with nu + e, e piecewise constant over 10 pieces, |e| <= margin per axis."""
    pieces = 10
    per = (len(t) - 1) // pieces
    out = np.empty((len(start), len(t), 3))
    pose = start
    out[:, 0] = start
    dt = t[1] - t[0]
    for p in range(pieces):
        e = rng.choice([-1.0, 1.0], size=nu.shape) * margin * rng.uniform(0.5, 1.0, size=nu.shape)
        seg = _flow(pose, nu + e, dt * np.arange(1, per + 1))
        out[:, 1 + p * per : 1 + (p + 1) * per] = seg
        pose = seg[:, -1]
    return out


def test_every_safe_input_is_safe_and_descends(
    coarse_problem: SymbolicProblem, coarse_controller: Controller
) -> None:
    rng = np.random.default_rng(7)
    totals, flights = _check(coarse_problem, coarse_controller, rng, np.zeros(3))
    assert flights > 20 * N_STATES
    assert totals == {"left_arena": 0, "touched_obstacle": 0, "no_descent": 0}


def test_checker_detects_an_unsound_controller(
    coarse_problem: SymbolicProblem, coarse_controller: Controller
) -> None:
    # The same checker, fed values that claim every cell wins in one step, must complain.
    forged = Controller(
        coarse_controller.tables,
        np.where(coarse_controller.values >= 0, 1, -1).astype(np.int32),
        coarse_controller.obstacles,
        coarse_controller.stats,
    )
    rng = np.random.default_rng(1)
    g = coarse_problem.grid
    t = np.linspace(0.0, coarse_problem.tau_s, N_STEPS + 1)
    # Fly every input (not only safe ones) from cells next to obstacle O1 and the walls.
    cells = np.argwhere(forged.values > 0)[::7]
    start = np.array(
        [
            g.cell_bounds(*map(int, c))[0]
            + 0.5 * np.array([g.cell_x_m, g.cell_y_m, g.heading_cell_rad])
            for c in cells
        ]
    )
    nu = coarse_controller.inputs[rng.integers(0, len(coarse_controller.inputs), len(start))]
    counts = _violations(
        coarse_problem, forged, _flow(start, nu, t), np.ones(len(start), dtype=np.int64)
    )
    assert counts["no_descent"] > 0
    assert counts["touched_obstacle"] + counts["left_arena"] > 0


def test_margin_guarantee_holds_under_velocity_errors(coarse: Scenario, cache_dir: Path) -> None:
    margin = TrackingMargin(0.01, 0.01, 0.01, "test")
    problem = SymbolicProblem.from_scenario(coarse.with_margin(margin))
    controller = synthesize(problem, cache_dir=cache_dir)
    assert controller.has_winning_start
    rng = np.random.default_rng(11)
    totals, flights = _check(problem, controller, rng, margin.as_array())
    assert flights > 10 * N_STATES
    assert totals == {"left_arena": 0, "touched_obstacle": 0, "no_descent": 0}


def test_margin_shrinks_or_keeps_the_winning_set(
    coarse: Scenario, coarse_controller: Controller, cache_dir: Path
) -> None:
    problem = SymbolicProblem.from_scenario(coarse.with_margin(TrackingMargin(0.02, 0.02, 0.02)))
    robust = synthesize(problem, cache_dir=cache_dir)
    win_robust = robust.values >= 0
    assert np.all(coarse_controller.values[win_robust] >= 0)
    assert win_robust.sum() <= (coarse_controller.values >= 0).sum()


@pytest.mark.parametrize("psi", [math.pi - 1e-3, -math.pi + 1e-3, math.pi, 3 * math.pi - 1e-3])
def test_heading_wrap_lookups_agree(coarse_controller: Controller, psi: float) -> None:
    state = (3.3, -1.1, psi)
    same = (3.3, -1.1, psi - 2 * math.pi)
    assert coarse_controller.value(state) == coarse_controller.value(same)
    np.testing.assert_array_equal(
        coarse_controller.safe_inputs(state), coarse_controller.safe_inputs(same)
    )
