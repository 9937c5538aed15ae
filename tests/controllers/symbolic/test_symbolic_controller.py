"""Controller lookups (grid edges, outside states), files and the paper's selection."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hil.controllers.symbolic import (
    Controller,
    ControllerFileError,
    EmptyInputSetError,
    cost,
    select,
)


@pytest.mark.parametrize(
    "state",
    [
        (4.5, 0.0, 0.0),  # x_max itself is outside (half-open cells)
        (-3.5 - 1e-9, 0.0, 0.0),
        (0.0, 3.0, 0.0),
        (0.0, -3.1, 0.0),
        (math.nan, 0.0, 0.0),
        (0.0, 0.0, math.inf),
        (1e300, -1e300, 0.0),
    ],
)
def test_states_outside_the_grid_get_nothing(
    coarse_controller: Controller, state: tuple[float, float, float]
) -> None:
    assert coarse_controller.value(state) == math.inf
    assert not coarse_controller.is_winning(state)
    assert coarse_controller.safe_inputs(state).shape == (0, 3)


def test_grid_edge_cells_are_looked_up(coarse_controller: Controller) -> None:
    g = coarse_controller.grid
    corner = (g.x_min_m, g.y_min_m, -math.pi)
    assert g.cell_of(corner) == (0, 0, 0)
    far = (g.x_max_m - 1e-9, g.y_max_m - 1e-9, math.pi - 1e-9)
    assert g.cell_of(far) == (g.nx - 1, g.ny - 1, g.npsi - 1)
    for state in (corner, far):
        inputs = coarse_controller.safe_inputs(state)
        assert inputs.shape[1] == 3
        assert coarse_controller.is_winning(state) == (coarse_controller.value(state) < math.inf)


def test_obstacle_cells_are_not_winning(coarse_controller: Controller) -> None:
    # Inside inflated O1 = [1.25, 2.75] x [-3.0, 0.5].
    assert not coarse_controller.is_winning((2.0, -1.0, 0.0))
    assert coarse_controller.safe_inputs((2.0, -1.0, 0.0)).shape == (0, 3)


def test_safe_inputs_are_a_subset_of_the_inputs(coarse_controller: Controller) -> None:
    state = (3.5, -1.5, 1.0)
    assert coarse_controller.is_winning(state)
    safe = coarse_controller.safe_inputs(state)
    assert len(safe) > 0
    rows = {tuple(r) for r in coarse_controller.inputs.tolist()}
    assert all(tuple(s) in rows for s in safe.tolist())


def test_save_and_load_round_trip(coarse_controller: Controller, tmp_path: Path) -> None:
    path = tmp_path / "ctrl.npz"
    coarse_controller.save(path)
    assert path.stat().st_size < 10 * 2**20
    loaded = Controller.load(path)
    np.testing.assert_array_equal(loaded.values, coarse_controller.values)
    np.testing.assert_array_equal(loaded.obstacles, coarse_controller.obstacles)
    assert loaded.grid == coarse_controller.grid
    assert loaded.stats == coarse_controller.stats
    rng = np.random.default_rng(3)
    for _ in range(50):
        state = (rng.uniform(-3.5, 4.5), rng.uniform(-3, 3), rng.uniform(-4, 4))
        np.testing.assert_array_equal(
            loaded.safe_inputs(state), coarse_controller.safe_inputs(state)
        )


def test_bad_controller_files_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ControllerFileError, match=r"missing\.npz"):
        Controller.load(tmp_path / "missing.npz")
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip")
    with pytest.raises(ControllerFileError, match=r"junk\.npz"):
        Controller.load(junk)
    other = tmp_path / "other.npz"
    np.savez(other, format=np.array("something-else"))
    with pytest.raises(ControllerFileError, match="something-else"):
        Controller.load(other)


def test_cost_matches_the_paper() -> None:
    previous = np.array([0.1, 0.0, 0.1])
    sigma = np.array([[0.2, 0.05, 0.0], [-0.1, 0.0, 0.1]])
    # beta = [sigma; sigma - previous]; W forward diag(1, 6, 1, 1, 1, 2.5),
    # backward diag(7.5, 3, 1, 1, 1, 2.5).
    forward = 0.2**2 + 6 * 0.05**2 + 0.0 + 0.1**2 + 0.05**2 + 2.5 * 0.1**2
    backward = 7.5 * 0.1**2 + 0.0 + 0.1**2 + 0.2**2 + 0.0 + 0.0
    np.testing.assert_allclose(cost(sigma, previous), [forward, backward])


def test_select_prefers_forward_and_smooth_yaw() -> None:
    safe = np.array([[-0.1, 0.0, 0.0], [0.1, 0.0, 0.0], [0.1, 0.0, 0.2]])
    np.testing.assert_array_equal(select(safe, np.array([0.1, 0.0, 0.0])), [0.1, 0.0, 0.0])
    # After a turn, keeping it costs 0.01 + 0.04 (yaw weight 1); stopping it costs
    # 0.01 + 2.5 * 0.04 (yaw-change weight 2.5): the turn is kept.
    np.testing.assert_array_equal(select(safe, np.array([0.1, 0.0, 0.2])), [0.1, 0.0, 0.2])
    with pytest.raises(EmptyInputSetError, match="no safe input"):
        select(np.empty((0, 3)))


def _safe_twin(controller: Controller, i: int, j: int, k: int) -> list[int]:
    """The definition of a safe input, in plain Python over the tables."""
    t = controller.tables
    nx, ny, npsi = controller.grid.shape
    v = controller.values
    if v[i, j, k] <= 0:
        return []
    out = []
    for u in range(t.n_inputs):
        ox0, ox1, oy0, oy1 = (int(a) for a in t.succ[k, u])
        succ = [
            (i + ox, j + oy, (k + ok) % npsi)
            for ox in range(ox0, ox1 + 1)
            for oy in range(oy0, oy1 + 1)
            for ok in range(int(t.heading[u, 0]), int(t.heading[u, 1]) + 1)
        ]
        tube = [
            (i + int(t.tube_x0[k, u]) + c, j + y)
            for c in range(int(t.tube_n[k, u]))
            for y in range(int(t.tube_y[k, u, c, 0]), int(t.tube_y[k, u, c, 1]) + 1)
        ]
        inside = all(0 <= a < nx and 0 <= b < ny for a, b, _ in succ) and all(
            0 <= a < nx and 0 <= b < ny for a, b in tube
        )
        if (
            inside
            and all(0 <= v[a, b, c] < v[i, j, k] for a, b, c in succ)
            and not any(controller.obstacles[a, b] for a, b in tube)
        ):
            out.append(u)
    return out


def test_safe_input_lookup_matches_its_definition(coarse_controller: Controller) -> None:
    rng = np.random.default_rng(9)
    g = coarse_controller.grid
    for _ in range(300):
        cell = (int(rng.integers(g.nx)), int(rng.integers(g.ny)), int(rng.integers(g.npsi)))
        got = coarse_controller.safe_input_indices_at(cell).tolist()
        assert got == _safe_twin(coarse_controller, *cell), cell
    for bad in ((-1, 0, 0), (g.nx, 0, 0), (0, g.ny, 0), (0, 0, g.npsi)):
        assert coarse_controller.safe_input_indices_at(bad).size == 0
