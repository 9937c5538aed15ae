"""A decision's contract against an independent computation.

The exact flow below integrates R(psi0 + r s) (u, v) in closed form (not the
abstraction's `displacement`), so it checks the tables and the judges together:
every arc from a point of the cell must be judged inside the tube and the successor,
and points pushed out must be judged out by the distance they were pushed. Tube
membership and distance are compared with a brute force over the tube's cells
(Grid.cell_bounds, one cell at a time).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.symbolic import Controller, DecisionContract, SymbolicError, cells_of

FloatArray = NDArray[np.float64]


def _flow(start: FloatArray, nu: FloatArray, t: FloatArray) -> FloatArray:
    """Exact pose after holding nu from start (3,) for times t (T,) -> (T, 3)."""
    x0, y0, psi0 = start
    u, v, r = nu
    psi = psi0 + r * t
    if abs(r) < 1e-12:
        x = x0 + (u * math.cos(psi0) - v * math.sin(psi0)) * t
        y = y0 + (u * math.sin(psi0) + v * math.cos(psi0)) * t
    else:
        x = x0 + (u * (np.sin(psi) - math.sin(psi0)) + v * (np.cos(psi) - math.cos(psi0))) / r
        y = y0 + (-u * (np.cos(psi) - math.cos(psi0)) + v * (np.sin(psi) - math.sin(psi0))) / r
    return np.stack([x, y, psi], axis=1)


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


def test_exact_arcs_from_the_cell_keep_the_contract(coarse_controller: Controller) -> None:
    rng = np.random.default_rng(3)
    grid = coarse_controller.grid
    values = coarse_controller.values
    winning = np.argwhere(values > 0)
    picks = winning[rng.integers(0, len(winning), 150)]
    # Heading cells that wrap (first and last) get a share of their own.
    wrap = np.argwhere((values > 0) & np.isin(np.arange(grid.npsi), [0, grid.npsi - 1]))
    picks[:40] = wrap[rng.integers(0, len(wrap), 40)]
    t = np.linspace(0.0, coarse_controller.tables.tau_s, 401)
    checked = descents = 0
    for cell in picks:
        cell_t = (int(cell[0]), int(cell[1]), int(cell[2]))
        lo, hi = grid.cell_bounds(*cell_t)
        safe = set(coarse_controller.safe_input_indices_at(cell_t).tolist())
        # Tube and successor are promises for every input, safe or not.
        for q in range(len(coarse_controller.inputs)):
            contract = DecisionContract.of(coarse_controller, cell_t, q)
            start = lo + rng.random(3) * (hi - lo)
            path = _flow(start, coarse_controller.inputs[q], t)
            assert contract.in_tube(path).all(), (cell_t, q)
            assert np.all(contract.tube_distance_m(path) == 0.0)
            end = path[-1:]
            assert contract.in_successor(end).all(), (cell_t, q)
            assert contract.successor_distance_m(end)[0] == 0.0
            assert contract.heading_distance_rad(end)[0] == 0.0
            if q in safe:
                assert contract.value_decreases(end).all(), (cell_t, q)
                descents += 1
            checked += 1
    assert checked == 150 * len(coarse_controller.inputs)
    assert descents > 150


def test_tube_membership_and_distance_match_a_brute_force(coarse_controller: Controller) -> None:
    rng = np.random.default_rng(5)
    grid = coarse_controller.grid
    cells = np.argwhere(coarse_controller.values > 0)[::97]
    for cell in cells:
        cell_t = (int(cell[0]), int(cell[1]), int(cell[2]))
        q = int(rng.integers(0, len(coarse_controller.inputs)))
        contract = DecisionContract.of(coarse_controller, cell_t, q)
        lo, _ = grid.cell_bounds(*cell_t)
        points = np.column_stack([
            lo[0] + rng.uniform(-1.2, 1.4, 40),
            lo[1] + rng.uniform(-1.2, 1.4, 40),
            rng.uniform(-math.pi, math.pi, 40),
        ])
        members = set(_tube_cells(contract))
        inside = contract.in_tube(points)
        dist = contract.tube_distance_m(points)
        for p, ins, d in zip(points, inside, dist, strict=True):
            # Tubes of unsafe inputs may reach past the grid: index cells without bounds.
            own = (
                math.floor((p[0] - grid.x_min_m) / grid.cell_x_m),
                math.floor((p[1] - grid.y_min_m) / grid.cell_y_m),
            )
            assert ins == (own in members)
            assert d == pytest.approx(_brute_distance(contract, p[0], p[1]), abs=1e-12)
            if not ins:
                assert d >= 0.0


def test_a_pushed_out_end_is_judged_out_by_the_push(coarse_controller: Controller) -> None:
    grid = coarse_controller.grid
    cell = (30, 20, 6)
    q = 22
    contract = DecisionContract.of(coarse_controller, cell, q)
    i0, j0, k0 = cell
    _, ox1, oy0, oy1 = contract.succ
    # The successor's right edge, from the grid's own cell bounds.
    right = grid.cell_bounds(i0 + ox1, j0 + oy0, k0)[1][0]
    bottom = grid.cell_bounds(i0, j0 + oy0, k0)[0][1]
    y_mid = 0.5 * (bottom + grid.cell_bounds(i0, j0 + oy1, k0)[1][1])
    lo, hi = grid.cell_bounds(*cell)
    end = _flow(0.5 * (lo + hi), coarse_controller.inputs[q], np.array([contract.tau_s]))
    for push in (0.013, 0.25, 0.7):
        pushed = np.array([[right + push, y_mid, end[0, 2]]])
        assert not contract.in_successor_cells(pushed)[0]
        assert contract.successor_distance_m(pushed)[0] == pytest.approx(push, abs=1e-12)
    # A heading pushed past the successor headings by an angle is judged by that angle.
    k_hi = contract.heading[1]
    top = -math.pi + (k0 + k_hi + 1) * grid.heading_cell_rad
    turned = np.array([[end[0, 0], end[0, 1], top + 0.05]])
    assert not contract.in_successor_heading(turned)[0]
    assert contract.heading_distance_rad(turned)[0] == pytest.approx(0.05, abs=1e-12)
    assert contract.in_successor_heading(turned - [0.0, 0.0, 0.1])[0]


def test_a_point_off_the_tube_is_out_by_its_distance(coarse_controller: Controller) -> None:
    grid = coarse_controller.grid
    contract = DecisionContract.of(coarse_controller, (30, 20, 0), 0)
    # Above the topmost cell of the first tube column.
    i = contract.cell[0] + contract.tube_x0
    j_top = contract.cell[1] + int(contract.tube_y[0, 1])
    lo, hi = grid.cell_bounds(i, j_top, 0)
    column_above = [j for (ii, j) in _tube_cells(contract) if ii == i and j > j_top]
    assert not column_above
    p = np.array([[0.5 * (lo[0] + hi[0]), hi[1] + 0.031, 0.0]])
    assert not contract.in_tube(p)[0]
    assert contract.tube_distance_m(p)[0] == pytest.approx(
        _brute_distance(contract, p[0, 0], p[0, 1]), abs=1e-12
    )
    assert 0.0 < contract.tube_distance_m(p)[0] <= 0.031 + 1e-12


def test_value_descent_uses_the_end_cell(coarse_controller: Controller) -> None:
    values = coarse_controller.values
    first = np.argwhere(values > 3)[0]
    cell = (int(first[0]), int(first[1]), int(first[2]))
    q = int(coarse_controller.safe_input_indices_at(cell)[0])
    contract = DecisionContract.of(coarse_controller, cell, q)
    grid = coarse_controller.grid
    centre = grid.cell_bounds(*cell).mean(axis=0)
    # Staying in the start cell does not descend; leaving the grid has no value.
    assert not contract.value_decreases(centre[None, :])[0]
    assert contract.end_values(np.array([[grid.x_max_m + 1.0, 0.0, 0.0]]))[0] == -1
    assert contract.value == values[cell]
    i, j, k = cells_of(grid, centre[None, :])
    assert (int(i[0]), int(j[0]), int(k[0])) == cell


def test_bad_cells_and_inputs_are_refused(coarse_controller: Controller) -> None:
    with pytest.raises(SymbolicError, match="outside the grid"):
        DecisionContract.of(coarse_controller, (-1, 0, 0), 0)
    with pytest.raises(SymbolicError, match="input index"):
        DecisionContract.of(coarse_controller, (0, 0, 0), len(coarse_controller.inputs))
