"""What one decision assumed for the next tau seconds, and judges of poses against it.

A decision at cell (i0, j0, k0) with reference p in force and input q relies on three
promises of the abstraction (abstraction.py; Reissig, Weber and Rungger 2016, IEEE TAC
62(4)), read from the tables of its class (0 when q holds p, 1 for a change, 2 for a first
decision):

- tube: over [0, tau + late] the centre stays in the swept tube's cells, x columns
  i0 + tube_x0 + c with y rows j0 + tube_y[c, 0] .. j0 + tube_y[c, 1];
- successor: at the next decision (tau .. tau + late) the state is in the cells
  i0 + ox_min .. i0 + ox_max, j0 + oy_min .. j0 + oy_max, headings
  k0 + ok_min .. k0 + ok_max (mod npsi);
- descent: the value there, with q in force, is strictly below the decision's value.

:class:`DecisionContract` holds these for one decision; its methods judge a
trajectory (N, 3) of poses (x m, y m, psi rad) at once. The runtime monitor,
replay and the campaign's judge share it, so they cannot disagree on what a
violation is. Cells are half-open (grid.py): a pose is inside when its cell is;
the size of a miss is the Euclidean distance of the centre to the closed cell
set (m), or the angle to the heading cells (rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.controller import Controller
from hil.controllers.symbolic.errors import SymbolicError
from hil.controllers.symbolic.grid import Grid
from hil.core.arrays import BoolArray, FloatArray, IntArray

__all__ = ["DecisionContract", "cells_of"]

_ANY_VALUE = 2**30


def cells_of(grid: Grid, poses: FloatArray) -> tuple[IntArray, IntArray, IntArray]:
    """Return the cell indices (i, j, k) of poses (N, 3), each shape (N,).

    i and j may lie outside [0, nx) and [0, ny) (poses outside the grid); k is the
    wrapped heading cell in [0, npsi). Same quantizer as :meth:`Grid.cell_of`.
    """
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    i = np.floor((p[:, 0] - grid.x_min_m) / grid.cell_x_m).astype(np.int64)
    j = np.floor((p[:, 1] - grid.y_min_m) / grid.cell_y_m).astype(np.int64)
    psi = np.mod(p[:, 2] + math.pi, 2.0 * math.pi)
    k = np.minimum(np.floor(psi / grid.heading_cell_rad).astype(np.int64), grid.npsi - 1)
    return i, j, k


def _box_distance(x: FloatArray, y: FloatArray, box: FloatArray) -> FloatArray:
    """Distance of points (N,) to closed boxes (B, 4) x0, x1, y0, y1 -> (N, B) (m)."""
    dx = np.maximum(np.maximum(box[None, :, 0] - x[:, None], x[:, None] - box[None, :, 1]), 0.0)
    dy = np.maximum(np.maximum(box[None, :, 2] - y[:, None], y[:, None] - box[None, :, 3]), 0.0)
    out: FloatArray = np.hypot(dx, dy)
    return out


@dataclass(frozen=True, slots=True, eq=False)
class DecisionContract:
    """What a decision assumed: tube, successor cells and value descent over tau.

    Attributes:
        grid: The state grid.
        cell: Start cell (i0, j0, k0) of the state the decision used.
        input_index: Chosen row q of the controller's inputs.
        nu_ref: The chosen input (u m/s, v m/s, r rad/s), shape (3,).
        tau_s: How long the decision holds (s).
        late_s: How much longer it may hold and stay covered (s).
        budget_class: 0 (hold), 1 (change) or 2 (a first decision).
        value: The decision's value (steps to target); -1 when nothing was safe; 2**30
            on a first decision (its end must win, at any value).
        tube_x0: First x offset of the tube (cells, relative to i0).
        tube_y: y offset range per tube column, shape (n_columns, 2), inclusive:
            column c is x offset tube_x0 + c.
        succ: Successor box (ox_min, ox_max, oy_min, oy_max), cells relative to (i0, j0).
        heading: Successor heading offsets (ok_min, ok_max), cells relative to k0.
        controller: The controller (values of the successor layer q).
        staying: A decision of the safety controller (docking was not winning): the end
            must lie in the safety set with q in force, not descend in value; `value` is
            then 1 and :meth:`end_values` 0 in the safety set, -1 outside it.
    """

    grid: Grid
    cell: tuple[int, int, int]
    input_index: int
    nu_ref: FloatArray
    tau_s: float
    late_s: float
    budget_class: int
    value: int
    tube_x0: int
    tube_y: NDArray[np.int32]
    succ: tuple[int, int, int, int]
    heading: tuple[int, int]
    controller: Controller
    staying: bool = False

    @staticmethod
    def of(
        controller: Controller,
        cell: tuple[int, int, int],
        input_index: int,
        reference_index: int,
        first: bool,
        staying: bool = False,
    ) -> DecisionContract:
        """Build the contract of choosing input `input_index` at `cell`.

        Args:
            controller: The controller the decision was taken with.
            cell: The decision's cell (i, j, k).
            input_index: The chosen input.
            reference_index: The input in force when the decision was taken.
            first: A first decision (every candidate budgeted as a change).
            staying: A decision of the safety controller (see the attribute).

        Raises:
            SymbolicError: The cell is outside the grid or an input index out of range.
        """
        grid = controller.grid
        i0, j0, k0 = (int(c) for c in cell)
        if not (0 <= i0 < grid.nx and 0 <= j0 < grid.ny and 0 <= k0 < grid.npsi):
            raise SymbolicError(f"cell {cell!r} is outside the grid {grid.shape!r}")
        t = controller.tables
        if not (0 <= input_index < t.n_inputs and 0 <= reference_index < t.n_inputs):
            raise SymbolicError(
                f"input indices {input_index!r}, {reference_index!r} not in [0, {t.n_inputs})"
            )
        q = int(input_index)
        c = 2 if first else (0 if q == reference_index else 1)
        n = int(t.tube_n[c, k0, q])
        s = t.succ[c, k0, q]
        h = t.heading[c, q]
        return DecisionContract(
            grid=grid,
            cell=(i0, j0, k0),
            input_index=q,
            nu_ref=t.inputs[q].copy(),
            tau_s=t.tau_s,
            late_s=t.late_s,
            budget_class=c,
            # A first decision promises only a winning end (any value); a staying one an
            # end in the safety set.
            value=1
            if staying
            else _ANY_VALUE
            if first
            else controller.cell_decision_value((i0, j0, k0), reference_index, False),
            tube_x0=int(t.tube_x0[c, k0, q]),
            tube_y=t.tube_y[c, k0, q, :n].copy(),
            succ=(int(s[0]), int(s[1]), int(s[2]), int(s[3])),
            heading=(int(h[0]), int(h[1])),
            controller=controller,
            staying=staying,
        )

    # ------------------------------------------------------------------ cell sets (metres)

    def tube_boxes(self) -> FloatArray:
        """Return the tube's columns as closed boxes in the arena (m), shape (n, 4).

        Rows (x_min, x_max, y_min, y_max), one per tube column.
        """
        g = self.grid
        i0, j0, _ = self.cell
        cols = i0 + self.tube_x0 + np.arange(len(self.tube_y))
        x0 = g.x_min_m + cols * g.cell_x_m
        y0 = g.y_min_m + (j0 + self.tube_y[:, 0]) * g.cell_y_m
        y1 = g.y_min_m + (j0 + self.tube_y[:, 1] + 1) * g.cell_y_m
        return np.stack([x0, x0 + g.cell_x_m, y0, y1], axis=1).astype(np.float64)

    def successor_box(self) -> FloatArray:
        """Return the successor cells' closed box in the arena (m), shape (4,): x0, x1, y0, y1."""
        g = self.grid
        i0, j0, _ = self.cell
        ox0, ox1, oy0, oy1 = self.succ
        return np.array(
            [
                g.x_min_m + (i0 + ox0) * g.cell_x_m,
                g.x_min_m + (i0 + ox1 + 1) * g.cell_x_m,
                g.y_min_m + (j0 + oy0) * g.cell_y_m,
                g.y_min_m + (j0 + oy1 + 1) * g.cell_y_m,
            ]
        )

    # ------------------------------------------------------------------ judges

    def in_tube(self, poses: FloatArray) -> BoolArray:
        """Return whether each pose's (x, y) cell is a tube cell, poses (N, 3) -> (N,)."""
        i, j, _ = cells_of(self.grid, poses)
        i0, j0, _ = self.cell
        c = i - i0 - self.tube_x0
        inside_cols = (c >= 0) & (c < len(self.tube_y))
        cc = np.clip(c, 0, max(len(self.tube_y) - 1, 0))
        oy = j - j0
        out: BoolArray = inside_cols & (oy >= self.tube_y[cc, 0]) & (oy <= self.tube_y[cc, 1])
        return out

    def tube_distance_m(self, poses: FloatArray) -> FloatArray:
        """Return each centre's distance to the nearest tube cell (m), (N, 3) -> (N,).

        Zero inside the tube (and on its boundary).
        """
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        d = _box_distance(p[:, 0], p[:, 1], self.tube_boxes())
        out: FloatArray = d.min(axis=1) if d.shape[1] else np.full(len(p), np.inf)
        return out

    def in_successor_cells(self, poses: FloatArray) -> BoolArray:
        """Return whether each pose's (x, y) cell is in the successor box, (N, 3) -> (N,)."""
        i, j, _ = cells_of(self.grid, poses)
        i0, j0, _ = self.cell
        ox0, ox1, oy0, oy1 = self.succ
        out: BoolArray = (i - i0 >= ox0) & (i - i0 <= ox1) & (j - j0 >= oy0) & (j - j0 <= oy1)
        return out

    def successor_distance_m(self, poses: FloatArray) -> FloatArray:
        """Return each centre's distance to the successor cells (m), (N, 3) -> (N,)."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        out: FloatArray = _box_distance(p[:, 0], p[:, 1], self.successor_box()[None, :])[:, 0]
        return out

    def in_successor_heading(self, poses: FloatArray) -> BoolArray:
        """Return whether each pose's heading cell is a successor heading, (N, 3) -> (N,)."""
        _, _, k = cells_of(self.grid, poses)
        npsi = self.grid.npsi
        lo, hi = self.heading
        if hi - lo + 1 >= npsi:
            return np.ones(len(k), dtype=bool)
        out: BoolArray = np.mod(k - self.cell[2] - lo, npsi) <= hi - lo
        return out

    def heading_distance_rad(self, poses: FloatArray) -> FloatArray:
        """Return each heading's angle to the successor heading cells (rad), (N, 3) -> (N,)."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        hp = self.grid.heading_cell_rad
        lo, hi = self.heading
        a0 = -math.pi + (self.cell[2] + lo) * hp  # the successor headings are [a0, a0 + w]
        w = (hi - lo + 1) * hp
        if w >= 2.0 * math.pi:
            return np.zeros(len(p))
        rel = np.mod(p[:, 2] - a0, 2.0 * math.pi)  # in [0, 2 pi)
        out: FloatArray = np.where(rel <= w, 0.0, np.minimum(rel - w, 2.0 * math.pi - rel))
        return out

    def in_successor(self, poses: FloatArray) -> BoolArray:
        """Return whether each pose's cell (x, y and heading) is a successor, (N, 3) -> (N,)."""
        out: BoolArray = self.in_successor_cells(poses) & self.in_successor_heading(poses)
        return out

    def end_values(self, poses: FloatArray) -> IntArray:
        """Return V (chosen input in force) at each pose's cell, (N, 3) -> (N,); -1 losing.

        For a staying decision: 0 in the safety set, -1 outside it.
        """
        i, j, k = cells_of(self.grid, poses)
        if self.staying:
            return np.where(self.controller.safe_at(self.input_index, i, j, k), 0, -1)
        out: IntArray = self.controller.values_at(self.input_index, i, j, k)
        return out

    def value_decreases(self, poses: FloatArray) -> BoolArray:
        """Return whether V at each pose's cell is winning and below the start value, (N,)."""
        v = self.end_values(poses)
        out: BoolArray = (v >= 0) & (v < self.value)
        return out
