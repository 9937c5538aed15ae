"""An independent check of the guarantee by simulation (not the controller's tables).

From random states (cell, reference p) of the tiny problem, every listed input is flown
from random true starts within the estimation bound of the cell, the body velocity off
the input by piecewise-constant errors within the budget's envelope of the input's
class (hold, change; a first decision uses the change envelope), integrated exactly
step by step over [0, tau + late]. Counted as violations: the hull leaving the arena,
the hull touching the real obstacle (separating axes on the rotated rectangle, not the
hull module), the centre inside an inflated obstacle, and an end in [tau, tau + late],
seen through an estimate within the bound, that does not win with the input in force at
a value below the decision's (any winning value for a first decision).

The checker is tested too: a controller solved on tables whose boxes were shrunk by
hand must be caught.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.symbolic import Controller, SymbolicProblem, Synthesizer, Tables
from hil.core.shapes import Rect
from tests.controllers.symbolic import tiny

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

N_POINTS = 3  # random starts per state and input
TOL_M = 1e-9


def _overlaps(poses: FloatArray, rect: Rect) -> NDArray[np.bool_]:
    """Return whether the hull at poses (n, 3) overlaps the closed rectangle by > TOL_M."""
    a, b = tiny.HULL[0] / 2, tiny.HULL[1] / 2
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    ac, as_ = np.abs(c), np.abs(s)
    hx, hy = (rect.x_max_m - rect.x_min_m) / 2, (rect.y_max_m - rect.y_min_m) / 2
    dx = poses[:, 0] - (rect.x_min_m + hx)
    dy = poses[:, 1] - (rect.y_min_m + hy)
    along = np.abs(dx * c + dy * s) < a + hx * ac + hy * as_ - TOL_M
    across = np.abs(-dx * s + dy * c) < b + hx * as_ + hy * ac - TOL_M
    in_x = np.abs(dx) < hx + a * ac + b * as_ - TOL_M
    in_y = np.abs(dy) < hy + a * as_ + b * ac - TOL_M
    out: NDArray[np.bool_] = along & across & in_x & in_y
    return out


def _outside_arena(poses: FloatArray, arena: Rect) -> NDArray[np.bool_]:
    a, b = tiny.HULL[0] / 2, tiny.HULL[1] / 2
    ac, as_ = np.abs(np.cos(poses[:, 2])), np.abs(np.sin(poses[:, 2]))
    ex, ey = a * ac + b * as_, a * as_ + b * ac
    x, y = poses[:, 0], poses[:, 1]
    out: NDArray[np.bool_] = (
        (x - ex < arena.x_min_m - TOL_M)
        | (x + ex > arena.x_max_m + TOL_M)
        | (y - ey < arena.y_min_m - TOL_M)
        | (y + ey > arena.y_max_m + TOL_M)
    )
    return out


def _picks(
    controller: Controller, rng: np.random.Generator, n_states: int, first: bool
) -> list[tuple[tuple[int, int, int], int, int, list[int]]]:
    """Return (cell, p, decision value, listed inputs) of random deciding states."""
    t = controller.tables
    out: list[tuple[tuple[int, int, int], int, int, list[int]]] = []
    layers = [controller.layer_values(p) for p in range(t.n_inputs)]
    while len(out) < n_states:
        p = int(rng.integers(t.n_inputs))
        # Winning states outside the target; for first decisions also any cell near them.
        win = np.argwhere(layers[p] > 0)
        if not len(win):
            continue
        pick = win[rng.integers(len(win))]
        if first:
            pick = np.clip(pick + rng.integers(-2, 3, 3), 0, np.array(controller.grid.shape) - 1)
        cell = (int(pick[0]), int(pick[1]), int(pick[2]))
        v0 = controller.cell_decision_value(cell, p, first)
        listed = controller.safe_input_indices_at(cell, p, first).tolist()
        if v0 > 0 and listed:
            out.append((cell, p, v0, listed))
    return out


def _violations(
    problem: SymbolicProblem,
    controller: Controller,
    rng: np.random.Generator,
    n_states: int,
    first: bool,
) -> tuple[dict[str, int], int]:
    """Fly every listed input of random states; count paths per kind of violation."""
    t = controller.tables
    g = problem.grid
    b = problem.budget
    eps, eps_psi = b.estimation_position_m, b.estimation_heading_rad
    rows = [
        (cell, p, v0, u)
        for cell, p, v0, listed in _picks(controller, rng, n_states, first)
        for u in listed
        for _ in range(N_POINTS)
    ]
    n = len(rows)
    start = np.array([g.cell_bounds(*r[0])[0] for r in rows])
    width = np.array([g.cell_x_m, g.cell_y_m, g.heading_cell_rad])
    start = start + rng.random((n, 3)) * width * (1.0 - 1e-9)
    offset = rng.uniform(-1.0, 1.0, (n, 3)) * [eps / math.sqrt(2.0), eps / math.sqrt(2.0), eps_psi]
    pose = start + offset  # the true start; the decision saw `start`
    u_idx = np.array([r[3] for r in rows])
    p_idx = np.array([r[1] for r in rows])
    v0 = np.array([r[2] for r in rows])
    cls = np.where(first | (u_idx != p_idx), 1, 0)
    env = b.envelopes[cls]  # (n, n_bins, 3)
    nu = t.inputs[u_idx]
    dt = b.bin_s / 20
    steps = round((problem.tau_s + problem.late_s) / dt)
    signs = rng.choice([-1.0, 1.0], size=(n, 3))
    scale = rng.uniform(0.8, 1.0, size=(n, 3))
    layers = np.stack([controller.layer_values(q) for q in range(t.n_inputs)])
    inflated = [o.inflate(problem.inflation_m) for o in problem.obstacles]
    bad = {"left_arena": np.zeros(n, bool), "touched_obstacle": np.zeros(n, bool)}
    bad["centre_in_inflated"] = np.zeros(n, bool)
    bad["no_descent"] = np.zeros(n, bool)
    for s in range(steps + 1):
        bad["left_arena"] |= _outside_arena(pose, problem.arena)
        for o in problem.obstacles:
            assert isinstance(o, Rect)
            bad["touched_obstacle"] |= _overlaps(pose, o)
        for o in inflated:
            assert isinstance(o, Rect)
            bad["centre_in_inflated"] |= (
                (o.x_min_m < pose[:, 0])
                & (pose[:, 0] < o.x_max_m)
                & (o.y_min_m < pose[:, 1])
                & (pose[:, 1] < o.y_max_m)
            )
        if s * dt >= problem.tau_s - 1e-9:
            seen = pose + rng.uniform(-1.0, 1.0, (n, 3)) * [
                eps / math.sqrt(2.0),
                eps / math.sqrt(2.0),
                eps_psi,
            ]
            i, j, k = tiny.cells(g, seen)
            ok = (i >= 0) & (i < g.nx) & (j >= 0) & (j < g.ny)
            v = np.full(n, -1)
            v[ok] = layers[u_idx[ok], i[ok], j[ok], k[ok]]
            bad["no_descent"] |= (v < 0) | ((v >= v0) & (not first))
        if s == steps:
            break
        if s % 10 == 0:
            redraw = rng.choice([-1.0, 1.0], size=(n, 3))
            signs[n // 2 :] = redraw[n // 2 :]
        bin_index = min(int((s * dt + 1e-12) / b.bin_s), b.n_bins - 1)
        e = signs * scale * env[:, bin_index]
        pose = tiny.flow(pose, nu + e, np.array([dt]))[:, 0]
    return {key: int(mask.sum()) for key, mask in bad.items()}, n


CLEAN = {"left_arena": 0, "touched_obstacle": 0, "centre_in_inflated": 0, "no_descent": 0}


@pytest.mark.parametrize("first", [False, True])
@pytest.mark.parametrize("which", ["zero", "budget"])
def test_every_listed_input_is_safe_and_descends(
    which: str,
    first: bool,
    problem: SymbolicProblem,
    controller: Controller,
    zero_problem: SymbolicProblem,
    zero_controller: Controller,
) -> None:
    prob, ctrl = (zero_problem, zero_controller) if which == "zero" else (problem, controller)
    rng = np.random.default_rng(7 + first)
    totals, flights = _violations(prob, ctrl, rng, 1500, first)
    assert flights > 8000
    assert totals == CLEAN


def _shrunk(tables: Tables) -> Tables:
    """Tables whose successor is one cell and whose tube is the start cell alone."""
    mid = (tables.succ[..., 0::2] + tables.succ[..., 1::2]) // 2
    succ = np.repeat(mid, 2, axis=-1)
    h_mid = (tables.heading[..., 0] + tables.heading[..., 1]) // 2
    return replace(
        tables,
        succ=np.ascontiguousarray(succ.astype(np.int32)),
        heading=np.ascontiguousarray(np.stack([h_mid, h_mid], axis=-1).astype(np.int32)),
        tube_x0=np.zeros_like(tables.tube_x0),
        tube_n=np.ones_like(tables.tube_n),
        tube_y=np.zeros_like(tables.tube_y[..., :1, :]),
        key="shrunk-by-hand",
    )


def test_checker_detects_an_unsound_controller(
    problem: SymbolicProblem, controller: Controller
) -> None:
    shrunk = Synthesizer(_shrunk(controller.tables), memo=False, use_cache=False).solve_problem(
        problem
    )
    assert shrunk.stats.winning_cells > controller.stats.winning_cells
    rng = np.random.default_rng(1)
    totals, flights = _violations(problem, shrunk, rng, 400, False)
    assert flights > 2000
    assert totals["no_descent"] > 0
    assert totals["touched_obstacle"] + totals["left_arena"] + totals["centre_in_inflated"] > 0


@pytest.mark.parametrize("first", [False, True])
def test_checker_detects_a_controller_that_ignores_the_budget(
    first: bool, problem: SymbolicProblem, zero_controller: Controller
) -> None:
    # Exact tracking assumed, the budget's errors flown: the checker must see it.
    rng = np.random.default_rng(2)
    totals, _flights = _violations(problem, zero_controller, rng, 1500, first)
    assert totals["no_descent"] > 0
