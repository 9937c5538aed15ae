"""Controller lookups (grid edges, outside states, layers), first decisions, files, selection."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.symbolic import (
    Controller,
    ControllerFileError,
    EmptyInputSetError,
    SymbolicProblem,
    cost,
    select,
)
from hil.controllers.symbolic.lattice import InputLattice
from tests.controllers.symbolic import tiny

# The tiny grid is [-1.5, 1.5) x [-1.0, 1.0) x [-pi, pi).
OUTSIDE = [
    (1.5, 0.0, 0.0),  # x_max itself is outside (half-open cells)
    (-1.5 - 1e-9, 0.0, 0.0),
    (0.0, 1.0, 0.0),
    (0.0, -1.1, 0.0),
    (math.nan, 0.0, 0.0),
    (0.0, math.nan, 0.0),
    (0.0, 0.0, math.nan),
    (0.0, 0.0, math.inf),
    (math.inf, 0.0, 0.0),
    (1e300, -1e300, 0.0),
]


@pytest.mark.parametrize("state", OUTSIDE)
def test_states_outside_the_grid_get_nothing(
    controller: Controller, state: tuple[float, float, float]
) -> None:
    for previous in (None, 0, controller.tables.n_inputs - 1):
        assert controller.value(state, previous) == math.inf
        assert not controller.is_winning(state, previous)
        for first in (False, True):
            assert controller.safe_inputs(state, previous, first).shape == (0, 3)
            assert controller.decision_value(state, previous, first) == math.inf


def test_cells_outside_the_grid_get_nothing(controller: Controller) -> None:
    g = controller.grid
    for bad in ((-1, 0, 0), (g.nx, 0, 0), (0, -1, 0), (0, g.ny, 0), (0, 0, g.npsi), (0, 0, -1)):
        for first in (False, True):
            assert controller.safe_input_indices_at(bad, 4, first).size == 0
    # Off-grid cells have no value in any layer (j = ny reads past the last row).
    for p in range(controller.tables.n_inputs):
        assert controller.cell_value((-1, 3, 0), p) == -1
        assert controller.cell_value((g.nx, 3, 0), p) == -1
        assert controller.cell_value((3, -1, 0), p) == -1
        assert controller.cell_value((3, g.ny, 0), p) == -1
    i = np.array([-1, g.nx, 0, 0, 5], dtype=np.int64)
    j = np.array([0, 0, -1, g.ny, 5], dtype=np.int64)
    k = np.array([0, 0, 0, 0, g.npsi + 2], dtype=np.int64)
    got = controller.values_at(4, i, j, k)
    np.testing.assert_array_equal(got[:4], [-1, -1, -1, -1])
    assert got[4] == controller.layer_values(4)[5, 5, 2]  # k wraps


def test_grid_edge_cells_are_looked_up(controller: Controller) -> None:
    g = controller.grid
    corner = (g.x_min_m, g.y_min_m, -math.pi)
    assert g.cell_of(corner) == (0, 0, 0)
    far = (g.x_max_m - 1e-9, g.y_max_m - 1e-9, math.pi - 1e-9)
    assert g.cell_of(far) == (g.nx - 1, g.ny - 1, g.npsi - 1)
    assert g.cell_of((0.0, 0.0, math.pi)) == g.cell_of((0.0, 0.0, -math.pi))
    for state in (corner, far):
        cell = g.cell_of(state)
        assert cell is not None
        for p in (None, 4, 13):
            v = controller.cell_value(cell, p)
            layer = controller.layer_values(controller.reference_index(p))
            assert v == layer[cell]
            assert controller.value(state, p) == (math.inf if v < 0 else v)
            assert controller.safe_inputs(state, p).shape[1] == 3
    # The hull does not fit at the corners: they lose.
    assert controller.value(corner) == math.inf
    assert controller.value(far) == math.inf


@pytest.mark.parametrize("psi", [math.pi - 1e-3, -math.pi + 1e-3, math.pi, 3 * math.pi - 1e-3])
def test_heading_wrap_lookups_agree(controller: Controller, psi: float) -> None:
    for xy in ((-0.5, 0.1), (-0.9, -0.4), (0.0, 0.3)):
        state = (*xy, psi)
        same = (*xy, psi - 2 * math.pi)
        for p in (None, 2, 22):
            assert controller.value(state, p) == controller.value(same, p)
            np.testing.assert_array_equal(
                controller.safe_inputs(state, p), controller.safe_inputs(same, p)
            )


def test_obstacle_cells_are_not_winning(problem: SymbolicProblem, controller: Controller) -> None:
    np.testing.assert_array_equal(controller.obstacles, problem.inflated_obstacle_mask())
    assert controller.obstacles.any()
    assert not controller.obstacles.flags.writeable
    at_rest = problem.heading_free()
    for p in range(controller.tables.n_inputs):
        v = controller.layer_values(p)
        assert np.all(v[controller.obstacles] == -1), p
        assert np.all(at_rest[v >= 0]), p  # the hull fits wherever a state wins
    # Inside the inflated obstacle [0.0, 0.6] x [-1.2, 0.3].
    assert not controller.is_winning((0.3, 0.2, 0.0))
    assert controller.safe_inputs((0.3, 0.2, 0.0), 4, True).shape == (0, 3)


def test_rest_layer_is_the_default(controller: Controller) -> None:
    rest = controller.rest_index
    np.testing.assert_array_equal(controller.inputs[rest], [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(controller.values, controller.layer_values(rest))
    assert not controller.values.flags.writeable
    for cell in np.argwhere(controller.values >= 0)[::50]:
        c = (int(cell[0]), int(cell[1]), int(cell[2]))
        assert controller.cell_value(c) == controller.cell_value(c, rest)
        np.testing.assert_array_equal(
            controller.safe_input_indices_at(c), controller.safe_input_indices_at(c, rest)
        )


def _expected_safe(
    controller: Controller,
    free: NDArray[np.bool_],
    layers: list[NDArray[np.int32]],
    cell: tuple[int, int, int],
    p: int,
    first: bool,
) -> tuple[list[int], int]:
    """The definition of the safe inputs and the decision value, from tables and layers."""
    t = controller.tables
    v = int(layers[p][cell])
    if (not first and v <= 0) or v == 0:
        return [], (v if not first else (0 if v == 0 else -1))
    limit = math.inf if first else v
    out = []
    best = -1
    lattice = InputLattice.of(t.inputs)
    for u, c in tiny.candidates(lattice, p, first):
        if not tiny.tube_free(t, free, c, cell, u):
            continue
        worst = tiny.worst_successor(layers, u, tiny.successor_cells(t, c, cell, u))
        if 0 <= worst < limit:
            out.append(u)
            best = worst + 1 if best < 0 else min(best, worst + 1)
    return out, (best if first else v)


@pytest.mark.parametrize("first", [False, True])
def test_safe_input_lookup_matches_its_definition(
    problem: SymbolicProblem, controller: Controller, first: bool
) -> None:
    rng = np.random.default_rng(9 + first)
    g = controller.grid
    t = controller.tables
    free = tiny.flat_free(problem, t)
    layers = [controller.layer_values(u) for u in range(t.n_inputs)]
    listed = 0
    for n in range(600):
        p = int(rng.integers(t.n_inputs))
        if n % 3:  # two picks in three from the layer's winning states outside the target
            win = np.argwhere(layers[p] > 0)
            pick = win[rng.integers(len(win))]
            cell = (int(pick[0]), int(pick[1]), int(pick[2]))
        else:
            cell = (int(rng.integers(g.nx)), int(rng.integers(g.ny)), int(rng.integers(g.npsi)))
        want, want_value = _expected_safe(controller, free, layers, cell, p, first)
        got = controller.safe_input_indices_at(cell, p, first).tolist()
        assert got == want, (cell, p, first)
        assert controller.cell_decision_value(cell, p, first) == want_value, (cell, p, first)
        listed += len(got)
        state = g.cell_bounds(*cell).mean(axis=0)
        np.testing.assert_array_equal(controller.safe_inputs(state, p, first), t.inputs[want])
        expected = math.inf if want_value < 0 else float(want_value)
        assert controller.decision_value(state, p, first) == expected
    assert listed > 200


def test_first_decisions_use_the_first_class(
    problem: SymbolicProblem, controller: Controller
) -> None:
    # A first decision tests every candidate, p included, against the class-2 tables:
    # its listed inputs are those of a controller whose class-0 and -1 tables are class 2's.
    t = controller.tables
    assert np.any(t.succ[2] != t.succ[0])
    free = tiny.flat_free(problem, t)
    lattice = InputLattice.of(t.inputs)
    layers = [controller.layer_values(u) for u in range(t.n_inputs)]
    differs = 0
    for p in range(t.n_inputs):
        for cell in np.argwhere(layers[p] > 0)[::7]:
            c = (int(cell[0]), int(cell[1]), int(cell[2]))
            got = set(controller.safe_input_indices_at(c, p, True).tolist())
            hold = set(controller.safe_input_indices_at(c, p, False).tolist())
            for u, _ in tiny.candidates(lattice, p, True):
                succ = tiny.successor_cells(t, 2, c, u)
                ok = tiny.tube_free(t, free, 2, c, u) and tiny.worst_successor(layers, u, succ) >= 0
                assert (u in got) == ok, (c, p, u)
            differs += got != hold
    assert differs > 0


def test_save_and_load_round_trip(controller: Controller, tmp_path: Path) -> None:
    path = tmp_path / "ctrl.npz"
    controller.save(path)
    assert path.stat().st_size < 2**20
    loaded = Controller.load(path)
    assert loaded.grid == controller.grid
    assert loaded.stats == controller.stats
    assert loaded.rest_index == controller.rest_index
    np.testing.assert_array_equal(loaded.obstacles, controller.obstacles)
    np.testing.assert_array_equal(loaded.values, controller.values)
    t, lt = controller.tables, loaded.tables
    assert (lt.tau_s, lt.late_s, lt.key, lt.budget_key) == (t.tau_s, t.late_s, t.key, t.budget_key)
    for name in ("inputs", "succ", "heading", "tube_x0", "tube_n", "tube_y", "hull_psi"):
        np.testing.assert_array_equal(getattr(lt, name), getattr(t, name), err_msg=name)
    for p in range(t.n_inputs):
        np.testing.assert_array_equal(loaded.layer_values(p), controller.layer_values(p))
    rng = np.random.default_rng(3)
    g = controller.grid
    for _ in range(200):
        state = (rng.uniform(-1.5, 1.5), rng.uniform(-1.0, 1.0), rng.uniform(-4, 4))
        p = int(rng.integers(t.n_inputs))
        for first in (False, True):
            np.testing.assert_array_equal(
                loaded.safe_inputs(state, p, first), controller.safe_inputs(state, p, first)
            )
            assert loaded.decision_value(state, p, first) == controller.decision_value(
                state, p, first
            )
    assert g.cell_of((0.0, 0.0, 0.0)) is not None


def _resave(src: Path, dst: Path, **changes: np.ndarray) -> None:
    with np.load(src) as data:
        arrays = {name: data[name] for name in data.files}
    arrays.update(changes)
    for name, value in changes.items():
        if value.size == 0:
            del arrays[name]
    np.savez(dst, **arrays)


def test_bad_controller_files_are_refused(controller: Controller, tmp_path: Path) -> None:
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
    good = tmp_path / "good.npz"
    controller.save(good)
    cases = {
        "old-format": ({"format": np.array("hil-symbolic-controller-1")}, "format"),
        "no-planes": ({"planes": np.empty(0)}, "planes"),
        "short-planes": (
            {"planes": np.zeros((1, 1, 1, 1, 8), dtype=np.uint64)},
            "do not fit",
        ),
        "two-class-tables": (
            {"succ": np.zeros((2, *controller.tables.succ.shape[1:]), dtype=np.int32)},
            "do not fit",
        ),
        "ragged-inputs": ({"inputs": controller.inputs[:-1]}, "do not fit"),
        "bad-grid": ({"grid": np.array([0.0, 0.0, -0.1, 0.1, 3, 3, 4])}, "cell widths"),
    }
    for name, (changes, match) in cases.items():
        bad = tmp_path / f"{name}.npz"
        _resave(good, bad, **changes)
        with pytest.raises(ControllerFileError, match=match):
            Controller.load(bad)


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
