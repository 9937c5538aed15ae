"""A decision's contract against an independent computation.

The exact flow (tests.controllers.symbolic.tiny.flow) integrates R(psi0 + r s) (u, v) in
closed form (not the abstraction's `displacement`), so it checks the tables and the
judges together: every arc from a point of the cell must be judged inside the tube and,
at every end time in [tau, tau + late], inside the successor; points pushed out must be
judged out by the distance they were pushed. Tube membership and distance are compared
with a brute force over the tube's cells (Grid.cell_bounds, one cell at a time).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.symbolic import Controller, DecisionContract, SymbolicError, cells_of
from hil.controllers.symbolic.lattice import InputLattice
from tests.controllers.symbolic import tiny

FloatArray = NDArray[np.float64]


def _tube_cells(contract: DecisionContract) -> list[tuple[int, int]]:
    i0, j0, _ = contract.cell
    return [
        (i0 + contract.tube_x0 + c, j0 + oy)
        for c, (y_lo, y_hi) in enumerate(contract.tube_y)
        for oy in range(int(y_lo), int(y_hi) + 1)
    ]


def _brute_distance(contract: DecisionContract, x: float, y: float) -> float:
    best = math.inf
    for i, j in _tube_cells(contract):
        lo, hi = contract.grid.cell_bounds(i, j, 0)
        dx = max(lo[0] - x, 0.0, x - hi[0])
        dy = max(lo[1] - y, 0.0, y - hi[1])
        best = min(best, math.hypot(dx, dy))
    return best


def _winning_cell(controller: Controller, p: int, above: int = 0) -> tuple[int, int, int]:
    cell = np.argwhere(controller.layer_values(p) > above)[0]
    return (int(cell[0]), int(cell[1]), int(cell[2]))


@pytest.mark.parametrize("which", ["zero", "budget"])
def test_exact_arcs_from_the_cell_keep_the_contract(
    which: str, controller: Controller, zero_controller: Controller
) -> None:
    ctrl = zero_controller if which == "zero" else controller
    t = ctrl.tables
    grid = ctrl.grid
    lattice = InputLattice.of(t.inputs)
    rng = np.random.default_rng(3)
    times = np.linspace(0.0, t.tau_s + t.late_s, 211)
    ends = times >= t.tau_s - 1e-12
    checked = descents = 0
    classes = set()
    for _ in range(60):
        p = int(rng.integers(t.n_inputs))
        win = np.argwhere(ctrl.layer_values(p) > 0)
        if not len(win):
            continue
        pick = win[rng.integers(len(win))]
        cell = (int(pick[0]), int(pick[1]), int(pick[2]))
        for first in (False, True):
            safe = set(ctrl.safe_input_indices_at(cell, p, first).tolist())
            # Tube and successor are promises for every allowed input, safe or not.
            for q, cls in tiny.candidates(lattice, p, first):
                contract = DecisionContract.of(ctrl, cell, q, p, first)
                assert contract.budget_class == cls
                classes.add(cls)
                start = tiny.points_in_cell(grid, cell, 12, rng)
                path = tiny.flow(start, np.repeat(t.inputs[q : q + 1], len(start), 0), times)
                poses = path.reshape(-1, 3)
                assert contract.in_tube(poses).all(), (cell, p, q, first)
                assert np.all(contract.tube_distance_m(poses) == 0.0)
                end = path[:, ends].reshape(-1, 3)
                assert contract.in_successor(end).all(), (cell, p, q, first)
                assert np.all(contract.successor_distance_m(end) == 0.0)
                assert np.all(contract.heading_distance_rad(end) == 0.0)
                if q in safe:
                    assert contract.value_decreases(end).all(), (cell, p, q, first)
                    descents += 1
                checked += 1
    assert classes == {0, 1, 2}
    assert checked > 1000
    assert descents > 50


def test_the_contract_reads_its_class_tables(controller: Controller) -> None:
    t = controller.tables
    p = 4
    cell = _winning_cell(controller, p)
    k = cell[2]
    for q, first, cls in ((p, False, 0), (5, False, 1), (p, True, 2), (5, True, 2)):
        c = DecisionContract.of(controller, cell, q, p, first)
        assert (c.budget_class, c.input_index, c.cell) == (cls, q, cell)
        np.testing.assert_array_equal(c.nu_ref, t.inputs[q])
        assert c.succ == tuple(int(v) for v in t.succ[cls, k, q])
        assert c.heading == tuple(int(v) for v in t.heading[cls, q])
        assert c.tube_x0 == t.tube_x0[cls, k, q]
        np.testing.assert_array_equal(c.tube_y, t.tube_y[cls, k, q, : t.tube_n[cls, k, q]])
        assert (c.tau_s, c.late_s) == (t.tau_s, t.late_s)
        assert c.value == (2**30 if first else controller.cell_value(cell, p))


def test_tube_membership_and_distance_match_a_brute_force(controller: Controller) -> None:
    rng = np.random.default_rng(5)
    grid = controller.grid
    t = controller.tables
    lattice = InputLattice.of(t.inputs)
    for n in range(30):
        p = int(rng.integers(t.n_inputs))
        cell = (
            int(rng.integers(grid.nx)),
            int(rng.integers(grid.ny)),
            int(rng.integers(grid.npsi)),
        )
        q, _ = tiny.candidates(lattice, p, False)[int(rng.integers(lattice.n_neighbours[p] + 1))]
        contract = DecisionContract.of(controller, cell, q, p, n % 3 == 0)
        lo, _ = grid.cell_bounds(*cell)
        points = np.column_stack(
            [
                lo[0] + rng.uniform(-0.5, 0.6, 40),
                lo[1] + rng.uniform(-0.5, 0.6, 40),
                rng.uniform(-math.pi, math.pi, 40),
            ]
        )
        members = set(_tube_cells(contract))
        inside = contract.in_tube(points)
        dist = contract.tube_distance_m(points)
        for pt, ins, d in zip(points, inside, dist, strict=True):
            # Tubes may reach past the grid: index cells without bounds.
            own = (
                math.floor((pt[0] - grid.x_min_m) / grid.cell_x_m),
                math.floor((pt[1] - grid.y_min_m) / grid.cell_y_m),
            )
            assert ins == (own in members)
            assert d == pytest.approx(_brute_distance(contract, pt[0], pt[1]), abs=1e-12)
            assert (d == 0.0) >= ins


def test_a_pushed_out_end_is_judged_out_by_the_push(controller: Controller) -> None:
    grid = controller.grid
    p = q = 22  # (0.1, 0.0, 0.0): straight ahead
    np.testing.assert_array_equal(controller.inputs[q], [0.1, 0.0, 0.0])
    cell = (10, 10, 12)
    contract = DecisionContract.of(controller, cell, q, p, False)
    i0, j0, k0 = cell
    _, ox1, oy0, oy1 = contract.succ
    right = grid.cell_bounds(i0 + ox1, j0 + oy0, k0)[1][0]
    bottom = grid.cell_bounds(i0, j0 + oy0, k0)[0][1]
    y_mid = 0.5 * (bottom + grid.cell_bounds(i0, j0 + oy1, k0)[1][1])
    lo, hi = grid.cell_bounds(*cell)
    end = tiny.flow(0.5 * (lo + hi)[None], controller.inputs[q][None], np.array([contract.tau_s]))
    for push in (0.013, 0.25, 0.7):
        pushed = np.array([[right + push, y_mid, end[0, 0, 2]]])
        assert not contract.in_successor_cells(pushed)[0]
        assert contract.successor_distance_m(pushed)[0] == pytest.approx(push, abs=1e-12)
    # A heading pushed past the successor headings by an angle is judged by that angle.
    k_hi = contract.heading[1]
    top = -math.pi + (k0 + k_hi + 1) * grid.heading_cell_rad
    turned = np.array([[end[0, 0, 0], end[0, 0, 1], top + 0.05]])
    assert not contract.in_successor_heading(turned)[0]
    assert contract.heading_distance_rad(turned)[0] == pytest.approx(0.05, abs=1e-12)
    assert contract.in_successor_heading(turned - [0.0, 0.0, 0.1])[0]
    # Headings are judged modulo 2 pi.
    assert contract.in_successor_heading(end[0] + [0.0, 0.0, 2 * math.pi]).all()


def test_a_point_off_the_tube_is_out_by_its_distance(controller: Controller) -> None:
    grid = controller.grid
    contract = DecisionContract.of(controller, (15, 10, 0), 13, 13, False)
    i = contract.cell[0] + contract.tube_x0
    j_top = contract.cell[1] + int(contract.tube_y[0, 1])
    lo, hi = grid.cell_bounds(i, j_top, 0)
    column_above = [j for (ii, j) in _tube_cells(contract) if ii == i and j > j_top]
    assert not column_above
    pt = np.array([[0.5 * (lo[0] + hi[0]), hi[1] + 0.031, 0.0]])
    assert not contract.in_tube(pt)[0]
    d = contract.tube_distance_m(pt)[0]
    assert d == pytest.approx(_brute_distance(contract, pt[0, 0], pt[0, 1]), abs=1e-12)
    assert 0.0 < d <= 0.031 + 1e-12


def test_value_descent_uses_the_chosen_inputs_layer(controller: Controller) -> None:
    grid = controller.grid
    lattice = InputLattice.of(controller.inputs)
    rng = np.random.default_rng(6)
    found = 0
    for p in range(controller.tables.n_inputs):
        v_p = controller.layer_values(p)
        for cell_a in np.argwhere(v_p > 1)[::5]:
            cell = (int(cell_a[0]), int(cell_a[1]), int(cell_a[2]))
            for q in controller.safe_input_indices_at(cell, p).tolist():
                if q == p:
                    continue
                contract = DecisionContract.of(controller, cell, q, p, False)
                assert contract.budget_class == 1
                assert lattice.distance_steps(p, q) == 1
                v_q = controller.layer_values(q)
                poses = np.column_stack(
                    [
                        rng.uniform(grid.x_min_m - 0.2, grid.x_max_m + 0.2, 3000),
                        rng.uniform(grid.y_min_m - 0.2, grid.y_max_m + 0.2, 3000),
                        rng.uniform(-4.0, 4.0, 3000),
                    ]
                )
                i, j, k = tiny.cells(grid, poses)
                ok = (i >= 0) & (i < grid.nx) & (j >= 0) & (j < grid.ny)
                want_q = np.full(len(poses), -1)
                want_q[ok] = v_q[i[ok], j[ok], k[ok]]
                want_p = np.full(len(poses), -1)
                want_p[ok] = v_p[i[ok], j[ok], k[ok]]
                np.testing.assert_array_equal(contract.end_values(poses), want_q)
                descends = (want_q >= 0) & (want_q < v_p[cell])
                np.testing.assert_array_equal(contract.value_decreases(poses), descends)
                # ... and the layers disagree on some of these poses: the test tells them apart.
                found += int(np.any(((want_p >= 0) & (want_p < v_p[cell])) != descends))
            if found >= 3:
                return
    pytest.fail("no change of reference whose layers differ")


def test_staying_put_does_not_descend(controller: Controller) -> None:
    p = controller.rest_index
    cell = _winning_cell(controller, p, above=1)
    q = int(controller.safe_input_indices_at(cell, p)[0])
    contract = DecisionContract.of(controller, cell, q, p, False)
    grid = controller.grid
    centre = grid.cell_bounds(*cell).mean(axis=0)
    if controller.cell_value(cell, q) >= controller.cell_value(cell, p):
        assert not contract.value_decreases(centre[None, :])[0]
    assert contract.end_values(np.array([[grid.x_max_m + 1.0, 0.0, 0.0]]))[0] == -1
    assert contract.value == controller.cell_value(cell, p)
    i, j, k = cells_of(grid, centre[None, :])
    assert (int(i[0]), int(j[0]), int(k[0])) == cell


def test_first_decisions_only_require_a_winning_end(controller: Controller) -> None:
    p = controller.rest_index
    lattice = InputLattice.of(controller.inputs)
    for q in lattice.allowed_after(p).tolist():
        contract = DecisionContract.of(controller, (15, 10, 0), q, p, True)
        assert contract.value == 2**30
        assert contract.budget_class == 2
        v_q = controller.layer_values(q)
        high = np.argwhere(v_q == v_q.max())[0]
        losing = np.argwhere(v_q < 0)[0]
        poses = np.array(
            [
                controller.grid.cell_bounds(*(int(a) for a in high)).mean(axis=0),
                controller.grid.cell_bounds(*(int(a) for a in losing)).mean(axis=0),
            ]
        )
        np.testing.assert_array_equal(contract.value_decreases(poses), [True, False])


def test_bad_cells_and_inputs_are_refused(controller: Controller) -> None:
    g = controller.grid
    m = controller.tables.n_inputs
    for cell in ((-1, 0, 0), (g.nx, 0, 0), (0, g.ny, 0), (0, 0, g.npsi), (0, 0, -1)):
        with pytest.raises(SymbolicError, match="outside the grid"):
            DecisionContract.of(controller, cell, 0, 0, False)
    for q, p in ((m, 0), (-1, 0), (0, m), (0, -1)):
        with pytest.raises(SymbolicError, match="input indices"):
            DecisionContract.of(controller, (0, 0, 0), q, p, False)
