"""The game over (cell, reference in force) on a small problem, checked independently.

- The compiled frontier kernel (serial and threaded) against the dense numpy solver.
- Soundness by simulation, not by the tables: from random winning states, every listed
  input is flown with the exact kinematics integrated finely, the body velocity off the
  input by random errors within the budget's envelope of the input's class, from random
  true starts within the estimation bound of the cell; the hull must stay in the arena
  and off the obstacles, the centre out of the inflated obstacles, and the end (seen
  through an estimate within the bound) must win with the input in force at a smaller
  value.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.symbolic import SymbolicProblem, Synthesizer, build_tables
from hil.controllers.symbolic.controller import Controller
from hil.controllers.symbolic.grid import Grid
from hil.controllers.symbolic.lattice import InputLattice
from hil.controllers.symbolic.reference import dense_fixed_point
from hil.core.shapes import Polygon, Rect, shapes_overlap
from hil.core.transient import TransientBudget
from tests.controllers.symbolic import tiny

FloatArray = NDArray[np.float64]

HULL = (0.3, 0.1)
ARENA = Rect(-1.5, 1.5, -1.0, 1.0)
OBSTACLE = Rect(0.2, 0.4, -1.0, 0.1)
INFLATION = 0.2


def _budget() -> TransientBudget:
    return tiny.budget()


@pytest.fixture(scope="module")
def problem() -> SymbolicProblem:
    axes = (np.array([0.0, 0.05, 0.1]), np.array([-0.05, 0.0, 0.05]), np.array([-0.1, 0.0, 0.1]))
    inputs = np.array(list(itertools.product(*axes)))
    return SymbolicProblem(
        grid=Grid(-1.5, -1.0, 0.1, 0.1, 30, 20, 12),
        inputs=inputs,
        tau_s=2.0,
        budget=_budget(),
        obstacles=(OBSTACLE,),
        inflation_m=INFLATION,
        target=Rect(-1.3, -0.7, -0.3, 0.5),
        arena=ARENA,
        hull_m=HULL,
        name="tiny",
    )


@pytest.fixture(scope="module")
def solved(problem: SymbolicProblem) -> tuple[Synthesizer, Controller]:
    tables = build_tables(problem.grid, problem.inputs, problem.tau_s, problem.budget, 0.1)
    synthesizer = Synthesizer(tables)
    return synthesizer, synthesizer.solve_problem(problem)


def test_kernel_equals_the_dense_solver(
    problem: SymbolicProblem, solved: tuple[Synthesizer, Controller]
) -> None:
    synthesizer, controller = solved
    t = synthesizer.tables
    flat = t.hull_psi.reshape(-1, 2)
    free = problem.free_masks(flat[:, 0], flat[:, 1])
    dense, levels = dense_fixed_point(t, free, problem.target_cells())
    assert levels == controller.stats.levels
    assert controller.stats.winning_cells > controller.stats.target_cells
    # memo=False: the memo would hand back the serial controller for the same masks.
    threaded = Synthesizer(t, threads=2, memo=False, use_cache=False).solve_problem(problem)
    assert threaded is not controller
    assert threaded.stats.threads == 2
    for p in range(t.n_inputs):
        np.testing.assert_array_equal(controller.layer_values(p), dense[p], err_msg=f"layer {p}")
        np.testing.assert_array_equal(threaded.layer_values(p), dense[p], err_msg=f"layer {p}")


def test_listed_inputs_are_one_step_from_the_reference(
    solved: tuple[Synthesizer, Controller],
) -> None:
    _, controller = solved
    lattice = InputLattice.of(controller.inputs)
    rng = np.random.default_rng(3)
    g = controller.grid
    seen = 0
    for _ in range(400):
        cell = (int(rng.integers(g.nx)), int(rng.integers(g.ny)), int(rng.integers(g.npsi)))
        p = int(rng.integers(controller.inputs.shape[0]))
        for u in controller.safe_input_indices_at(cell, p):
            assert lattice.distance_steps(p, int(u)) <= 1
            seen += 1
    assert seen > 0


def _envelope_error(
    rng: np.random.Generator, env: FloatArray, bin_s: float, t: FloatArray
) -> FloatArray:
    """Random velocity errors (T, 3) within env (n_bins, 3), piecewise constant."""
    out = np.empty((len(t), 3))
    pieces = np.sort(rng.uniform(0.0, t[-1], size=12))
    signs = rng.choice([-1.0, 1.0], size=(13, 3))
    scale = rng.uniform(0.6, 1.0, size=(13, 3))
    piece = np.searchsorted(pieces, t)
    b = np.minimum((t / bin_s).astype(int), env.shape[0] - 1)
    out[:] = signs[piece] * scale[piece] * env[b]
    return out


def _fly(start: FloatArray, nu: FloatArray, dt: float) -> FloatArray:
    """Integrate x' = R(psi) (u, v), psi' = r with midpoint steps: (T, 3) -> poses (T, 3)."""
    poses = np.empty((len(nu), 3))
    poses[0] = start
    for n in range(len(nu) - 1):
        psi_mid = poses[n, 2] + 0.5 * dt * nu[n, 2]
        c, s = math.cos(psi_mid), math.sin(psi_mid)
        u, v, r = nu[n]
        poses[n + 1] = poses[n] + dt * np.array([c * u - s * v, s * u + c * v, r])
    return poses


@pytest.mark.parametrize("first", [False, True])
def test_listed_inputs_are_safe_when_flown(
    problem: SymbolicProblem, solved: tuple[Synthesizer, Controller], first: bool
) -> None:
    _, controller = solved
    budget = problem.budget
    g = problem.grid
    rng = np.random.default_rng(11 + first)
    dt = 0.005
    horizon = problem.tau_s + problem.late_s
    t = np.arange(0.0, horizon + dt / 2, dt)
    inflated = OBSTACLE.inflate(INFLATION)
    eps, eps_psi = budget.estimation_position_m, budget.estimation_heading_rad
    flights = 0
    layers = {p: np.argwhere(controller.layer_values(p) > 0) for p in range(len(problem.inputs))}
    for _ in range(400):
        p = int(rng.integers(controller.inputs.shape[0]))
        if not len(layers[p]):
            continue
        i, j, k = (int(c) for c in layers[p][rng.integers(len(layers[p]))])
        cell = (i, j, k)
        v0 = controller.cell_decision_value(cell, p, first)
        if v0 <= 0:
            continue
        lo, hi = g.cell_bounds(*cell)
        for u in controller.safe_input_indices_at(cell, p, first):
            cls = 2 if first else (0 if int(u) == p else 1)
            start = rng.uniform(lo, hi)
            start[:2] += rng.uniform(-eps, eps, size=2) / math.sqrt(2.0)
            start[2] += rng.uniform(-eps_psi, eps_psi)
            nu = controller.inputs[u] + _envelope_error(rng, budget.envelopes[cls], budget.bin_s, t)
            path = _fly(start, nu, dt)
            flights += 1
            for pose in path[::10]:
                hull = Polygon.rotated_rect((pose[0], pose[1]), HULL, pose[2])
                v = hull.vertices()
                assert v[:, 0].min() >= ARENA.x_min_m
                assert v[:, 0].max() <= ARENA.x_max_m
                assert v[:, 1].min() >= ARENA.y_min_m
                assert v[:, 1].max() <= ARENA.y_max_m
                assert not shapes_overlap(hull, OBSTACLE), (cell, p, int(u), pose)
                assert not (
                    inflated.x_min_m < pose[0] < inflated.x_max_m
                    and inflated.y_min_m < pose[1] < inflated.y_max_m
                )
            # Any end in [tau, tau + late], seen through an estimate within the bound.
            for end in path[t >= problem.tau_s - 1e-9][::5]:
                seen = end + np.array([*rng.uniform(-eps, eps, 2) / math.sqrt(2.0), 0.0])
                seen[2] += rng.uniform(-eps_psi, eps_psi)
                value = controller.value(seen, int(u))
                # A first decision promises a winning end; later ones a smaller value.
                assert value < (math.inf if first else v0), (cell, p, int(u), first, end, v0)
    assert flights > 300


def test_save_and_load_round_trip(solved: tuple[Synthesizer, Controller], tmp_path: Path) -> None:
    _, controller = solved
    path = tmp_path / "controller.npz"
    controller.save(path)
    loaded = Controller.load(path)
    assert loaded.stats == controller.stats
    # Every figure round-trips, also those of an early or a stored controller.
    controller.stats = replace(original := controller.stats, complete=False, loaded_seconds=0.25)
    try:
        controller.save(path)
        assert Controller.load(path).stats == controller.stats
    finally:
        controller.stats = original
    g = controller.grid
    for p in range(controller.inputs.shape[0]):
        np.testing.assert_array_equal(loaded.layer_values(p), controller.layer_values(p))
    rng = np.random.default_rng(5)
    for _ in range(200):
        cell = (int(rng.integers(g.nx)), int(rng.integers(g.ny)), int(rng.integers(g.npsi)))
        p = int(rng.integers(controller.inputs.shape[0]))
        for first in (False, True):
            np.testing.assert_array_equal(
                loaded.safe_input_indices_at(cell, p, first),
                controller.safe_input_indices_at(cell, p, first),
            )
