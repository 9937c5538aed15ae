"""The finite abstraction: translation-invariant cell-offset tables, cached on disk.

For body velocities nu = (u, v, r) held over t, the displacement is R(psi0) d(nu, t) with

    d = (u t, v t)                                                    if r = 0
    d = ((u sin rt + v (cos rt - 1)) / r, (u (1 - cos rt) + v sin rt) / r)   otherwise

(DESIGN.md), independent of (x0, y0). So a cell's successors under an input depend only
on its heading cell and the input: one table of offset boxes per (heading cell, input),
computed once per grid and never per obstacle layout.

Soundness (feedback refinement relations, Reissig, Weber and Rungger 2016, IEEE TAC
62(4)): every box below contains every motion from every point of the cell.

- Rotating d over the cell's heading interval traces a circle arc; its bounding box is
  exact (end points plus the axis crossings inside the interval).
- Between two time samples the nominal path stays within speed * dt / 2 of one of them
  (|d'| = |(u, v)|), so each sub-interval box of the swept tube is the union of the
  sampled arc boxes padded by that distance: it bounds the motion over its whole span.
  An axis needs no padding where its velocity cannot change sign over the span (the
  world velocity direction psi0 + atan2(v, u) + r t avoids the axis' critical angles
  for every psi0 in the cell): the motion along it is then monotone between samples.
- The real closed loop strays from the arc by at most rho(t) in position and theta(t)
  in heading (:class:`DeviationBudget`, derived from the low level the vessel runs:
  :mod:`hil.core.transient`), per class: 0 when the period holds the previous
  reference, 1 when it changes it by at most one grid step per axis (class 1's bound
  is the larger of both). rho at the end of each span pads every box of the span.
- Estimation: decisions use the estimated pose, within eps_m and eps_rad of the true
  one. The start heading interval is widened by eps_rad and every tube box padded by
  eps_m (the true start lies there); the successor is padded by 2 eps_m and its
  heading offsets by 2 eps_rad, so it holds the *next estimated* cell.
- A command may be held late_s past tau (a late tick): the successor holds every end
  in [tau, tau + late_s] and the tube runs to tau + late_s.
- The hull: ``hull_psi`` gives the headings the hull may take over the period, per
  start heading cell and yaw-rate value; the synthesis tests the tube against the
  cells free for the hull over that range (:mod:`hull`).
- Half-open cells: a displacement interval [lo, hi] reaches cell offsets
  floor(lo / h) .. ceil(hi / h); the heading offset interval likewise. Bounds within
  1e-9 cell widths of a cell edge (5e-11 m on the paper grid) snap to it, so that
  rounding (cos(pi / 2) = 6e-17) does not add a whole row of cells.
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.errors import GridError
from hil.controllers.symbolic.grid import Grid
from hil.core.arrays import FloatArray

I32Array = NDArray[np.int32]

__all__ = [
    "Tables",
    "arc_poses",
    "build_tables",
    "default_cache_dir",
    "displacement",
    "tables_for",
]

_VERSION = 3

N_CLASSES = 3
"""Budget classes of the tables: 0 hold, 1 change, 2 first command."""
_SNAP = 1e-9  # cell widths: bounds this close to a cell edge snap onto it


def default_cache_dir() -> Path:
    """Return $HIL_CACHE_DIR, else ~/.cache/hil/symbolic."""
    env = os.environ.get("HIL_CACHE_DIR")
    return Path(env) if env else Path.home() / ".cache" / "hil" / "symbolic"


class DeviationBudget(Protocol):
    """How far the real closed loop may stray from the exact arc (see :mod:`hil.core.transient`).

    Class 0 covers a command period that holds the previous reference, class 1 one that
    changes it by at most one grid step per axis, class 2 (when there is one) a first
    command (start, or after a stop or hold), the vessel possibly moving.
    """

    @property
    def n_classes(self) -> int:
        """Number of classes the budget holds (2 or 3)."""
        ...

    @property
    def estimation_position_m(self) -> float:
        """Bound on the estimate's position error (m)."""
        ...

    @property
    def estimation_heading_rad(self) -> float:
        """Bound on the estimate's heading error (rad)."""
        ...

    def position_bound_m(self, cls: int, speed_mps: FloatArray, t_s: FloatArray) -> FloatArray:
        """Return the position deviation bound, shape (m, T), for speeds (m,) at times (T,)."""
        ...

    def heading_bound_rad(self, cls: int, t_s: FloatArray) -> FloatArray:
        """Return the heading deviation bound, shape (T,), at times (T,)."""
        ...

    def digest(self) -> str:
        """Return a stable hash of the budget's numbers."""
        ...


@dataclass(frozen=True, slots=True, eq=False)
class Tables:
    """Cell-offset tables of one grid, input set, tau and deviation budget, per class.

    Class c = 0 budgets a period that holds the previous reference, c = 1 one that
    changes it (one grid step per axis at most), c = 2 a first command (start, or after
    a stop or hold); each class's boxes contain the lower classes'.

    Attributes:
        grid: The state grid.
        inputs: Inputs (surge m/s, sway m/s, yaw rate rad/s), shape (m, 3).
        tau_s: Command period (s).
        late_s: How late a command may come and stay covered (s): every bound holds
            up to tau + late.
        succ: Successor offset boxes, shape (3, npsi, m, 4) indexed [c, k, input]:
            (ox_min, ox_max, oy_min, oy_max) in cells, inclusive; they hold the next
            *estimated* cell (the true end padded by the estimation bound once more).
        heading: Successor heading offsets, shape (3, m, 2): (ok_min, ok_max), inclusive.
        tube_x0: First x offset of the swept tube, shape (3, npsi, m).
        tube_n: Number of tube columns, shape (3, npsi, m).
        tube_y: Tube column y ranges, shape (3, npsi, m, c_max, 2): column c is x
            offset tube_x0 + c with y offsets tube_y[..., c, 0] .. tube_y[..., c, 1].
        hull_psi: Headings the hull may take during the period, shape (3, npsi, n_yaw, 2)
            (rad, lo <= hi, not wrapped) for start cell k and the input's yaw-rate value.
        yaw_index: Each input's yaw-rate value index into hull_psi, shape (m,).
        budget_key: Digest of the deviation budget.
        key: Hash of everything the tables depend on.
    """

    grid: Grid
    inputs: FloatArray
    tau_s: float
    late_s: float
    succ: I32Array
    heading: I32Array
    tube_x0: I32Array
    tube_n: I32Array
    tube_y: I32Array
    hull_psi: FloatArray
    yaw_index: I32Array
    budget_key: str
    key: str

    @property
    def n_inputs(self) -> int:
        """Return the number of inputs m."""
        return int(self.inputs.shape[0])

    def nbytes(self) -> int:
        """Return the memory the tables hold (bytes)."""
        return sum(
            a.nbytes
            for a in (
                self.succ,
                self.heading,
                self.tube_x0,
                self.tube_n,
                self.tube_y,
                self.hull_psi,
                self.yaw_index,
            )
        )

    def hull_range_index(self) -> I32Array:
        """Return each (c, k, input)'s row of ``hull_psi.reshape(-1, 2)``, shape (3, npsi, m)."""
        n_cls, npsi, n_yaw, _ = self.hull_psi.shape
        base = (np.arange(n_cls)[:, None] * npsi + np.arange(npsi)[None, :]) * n_yaw
        out: I32Array = (base[:, :, None] + self.yaw_index[None, None, :]).astype(np.int32)
        return out


def displacement(inputs: FloatArray, t_s: FloatArray) -> FloatArray:
    """Return d(nu, t) in the start body frame, shape (m, T, 2), for inputs (m, 3), times (T,)."""
    u = inputs[:, 0:1]
    v = inputs[:, 1:2]
    r = inputs[:, 2:3]
    t = np.asarray(t_s, dtype=np.float64)[None, :]
    straight = np.abs(r) < 1e-12
    r_safe = np.where(straight, 1.0, r)
    rt = r_safe * t
    dx = np.where(straight, u * t, (u * np.sin(rt) + v * (np.cos(rt) - 1.0)) / r_safe)
    dy = np.where(straight, v * t, (u * (1.0 - np.cos(rt)) + v * np.sin(rt)) / r_safe)
    return np.stack([dx, dy], axis=-1)


def arc_poses(state: FloatArray, inputs: FloatArray, t_s: FloatArray) -> FloatArray:
    """Return the exact arcs' poses from `state` under each input held, shape (m, T, 3).

    state: pose (x m, y m, psi rad); inputs (m, 3): body velocities (u m/s, v m/s, r rad/s)
    held from t = 0; t_s (T,): times (s). Rows (x m, y m, psi rad) in the arena frame.
    """
    x0, y0, psi0 = (float(v) for v in np.asarray(state, dtype=np.float64).reshape(3))
    inputs = np.asarray(inputs, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(t_s, dtype=np.float64)
    d = displacement(inputs, t)  # (m, T, 2) in the start body frame
    c, s = math.cos(psi0), math.sin(psi0)
    x = x0 + c * d[..., 0] - s * d[..., 1]
    y = y0 + s * d[..., 0] + c * d[..., 1]
    psi = psi0 + inputs[:, 2:3] * t[None, :]
    out: FloatArray = np.stack([x, y, psi], axis=-1)
    return out


def _cos_range(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Return min and max of cos over [a, b] (b - a < 2 pi), elementwise."""
    two_pi = 2.0 * math.pi
    ca, cb = np.cos(a), np.cos(b)
    has_max = np.ceil(a / two_pi) * two_pi <= b
    has_min = np.ceil((a - math.pi) / two_pi) * two_pi + math.pi <= b
    return (np.where(has_min, -1.0, np.minimum(ca, cb)), np.where(has_max, 1.0, np.maximum(ca, cb)))


def _arc_boxes(d: FloatArray, psi_lo: FloatArray, psi_hi: FloatArray) -> FloatArray:
    """Return boxes of {R(psi) d : psi in [lo, hi]}, shape (npsi, m, T, 4): xlo, xhi, ylo, yhi.

    Args:
        d: Displacements, shape (m, T, 2).
        psi_lo: Lower heading per cell, shape (npsi,).
        psi_hi: Upper heading per cell, shape (npsi,).
    """
    rho = np.hypot(d[..., 0], d[..., 1])[None]
    phi = np.arctan2(d[..., 1], d[..., 0])[None]
    a = phi + psi_lo[:, None, None]
    b = phi + psi_hi[:, None, None]
    cmin, cmax = _cos_range(a, b)
    smin, smax = _cos_range(a - 0.5 * math.pi, b - 0.5 * math.pi)
    return np.stack([rho * cmin, rho * cmax, rho * smin, rho * smax], axis=-1)


def _offsets(lo: FloatArray, hi: FloatArray, width: float) -> tuple[I32Array, I32Array]:
    return (
        np.floor(lo / width + _SNAP).astype(np.int32),
        np.ceil(hi / width - _SNAP).astype(np.int32),
    )


def _contains_angle(lo: FloatArray, hi: FloatArray, angle: float) -> NDArray[np.bool_]:
    """Return True where [lo, hi] contains angle + n pi for some integer n."""
    return np.asarray(np.ceil((lo - angle) / math.pi) * math.pi + angle <= hi, dtype=bool)


def _heading_offsets(shift_cells: FloatArray, lower: bool) -> I32Array:
    # A shift that is an integer up to rounding moves the cell onto cells exactly.
    nearest = np.round(shift_cells)
    exact = np.abs(shift_cells - nearest) < 1e-9
    bound = np.floor(shift_cells) if lower else np.ceil(shift_cells)
    return np.where(exact, nearest, bound).astype(np.int32)


def _key(
    grid: Grid, inputs: FloatArray, tau_s: float, late_s: float, budget_key: str, n_sub: int
) -> str:
    h = hashlib.sha256()
    h.update(repr((_VERSION, grid.digest(), tau_s, late_s, budget_key, n_sub)).encode())
    h.update(np.ascontiguousarray(inputs, dtype=np.float64).tobytes())
    return h.hexdigest()[:20]


def _check_inputs(inputs: FloatArray, tau_s: float, late_s: float) -> FloatArray:
    arr = np.ascontiguousarray(inputs, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0 or not np.all(np.isfinite(arr)):
        raise GridError(f"inputs must be a finite (m, 3) array, got shape {arr.shape!r}")
    if not (math.isfinite(tau_s) and tau_s > 0.0):
        raise GridError(f"tau_s must be positive, got {tau_s!r}")
    if not (math.isfinite(late_s) and late_s >= 0.0):
        raise GridError(f"late_s must be finite and >= 0, got {late_s!r}")
    return arr


@dataclass(frozen=True, slots=True)
class _ClassTables:
    succ: I32Array  # (npsi, m, 4)
    heading: I32Array  # (m, 2)
    tube_x0: I32Array  # (npsi, m)
    tube_n: I32Array  # (npsi, m)
    tube_y: I32Array  # (npsi, m, c, 2)
    hull_psi: FloatArray  # (npsi, n_yaw, 2)


def _class_tables(
    grid: Grid,
    inputs: FloatArray,
    tau_s: float,
    horizon_s: float,
    rho: Callable[[FloatArray], FloatArray],
    theta: Callable[[FloatArray], FloatArray],
    eps_m: float,
    eps_rad: float,
    n_sub: int,
    per_sub: int,
) -> _ClassTables:
    """Tables of one class: rho(t) (m, T) and theta(t) (T,) bound the deviation from the arc."""
    hp = grid.heading_cell_rad
    # The true start heading lies within eps_rad of the (estimated) cell.
    psi_lo = np.asarray(-math.pi + hp * np.arange(grid.npsi), dtype=np.float64) - eps_rad
    psi_hi = psi_lo + hp + 2.0 * eps_rad
    n_t = n_sub * per_sub
    t = np.linspace(0.0, horizon_s, n_t + 1)
    boxes = _arc_boxes(displacement(inputs, t), psi_lo, psi_hi)  # (npsi, m, T, 4)
    th_end = float(theta(t[-1:])[0])
    first = min(math.floor(tau_s / (horizon_s / n_t) + 1e-9), n_t)
    tube_x0, tube_n, tube_y = _swept_tube(
        grid, inputs, t, boxes, psi_lo, psi_hi, rho, theta, eps_m, n_sub, per_sub
    )
    return _ClassTables(
        succ=_successor_offsets(grid, inputs, t, boxes, first, rho, eps_m),
        heading=_heading_range(inputs[:, 2], float(t[first]), horizon_s, th_end, eps_rad, hp),
        tube_x0=tube_x0,
        tube_n=tube_n,
        tube_y=tube_y,
        hull_psi=_hull_headings(inputs[:, 2], psi_lo, psi_hi, horizon_s, th_end),
    )


def _successor_offsets(
    grid: Grid,
    inputs: FloatArray,
    t: FloatArray,
    boxes: FloatArray,
    first: int,
    rho: Callable[[FloatArray], FloatArray],
    eps_m: float,
) -> I32Array:
    """Return the successor's cell offsets (x0, x1, y0, y1), shape (npsi, m, 4).

    Every end time t[first:] in [tau, tau + late], padded for the deviation and, once
    more, for the estimate (the next decision's cell is the estimated one).
    """
    dt = float(t[-1]) / (t.shape[0] - 1)  # the step of t (s), as linspace made it
    speed = np.hypot(inputs[:, 0], inputs[:, 1])  # (m,)
    ends = boxes[:, :, first:, :]
    between_end = speed[None, :] * dt / 2.0 if ends.shape[2] > 1 else 0.0
    pad_end = (rho(t[-1:])[:, 0] + 2.0 * eps_m)[None, :] + between_end
    sx0, sx1 = _offsets(
        ends[..., 0].min(axis=2) - pad_end, ends[..., 1].max(axis=2) + pad_end, grid.cell_x_m
    )
    sy0, sy1 = _offsets(
        ends[..., 2].min(axis=2) - pad_end, ends[..., 3].max(axis=2) + pad_end, grid.cell_y_m
    )
    out: I32Array = np.stack([sx0, sx1, sy0, sy1], axis=-1).astype(np.int32)
    return out


def _heading_range(
    r_in: FloatArray, t_first: float, horizon_s: float, th_end: float, eps_rad: float, hp: float
) -> I32Array:
    """Return the successor's heading-cell offsets (lower, upper) per input, shape (m, 2).

    r_in: yaw rates (m,) (rad/s); t_first: the first end time (s); th_end: the heading
    deviation bound at the horizon (rad); hp: the heading cell (rad).
    """
    turn_min = np.minimum(r_in * t_first, r_in * horizon_s)
    turn_max = np.maximum(r_in * t_first, r_in * horizon_s)
    out: I32Array = np.stack(
        [
            _heading_offsets((turn_min - th_end - 2.0 * eps_rad) / hp, lower=True),
            _heading_offsets((turn_max + th_end + 2.0 * eps_rad) / hp, lower=False),
        ],
        axis=-1,
    ).astype(np.int32)
    return out


def _swept_tube(
    grid: Grid,
    inputs: FloatArray,
    t: FloatArray,
    boxes: FloatArray,
    psi_lo: FloatArray,
    psi_hi: FloatArray,
    rho: Callable[[FloatArray], FloatArray],
    theta: Callable[[FloatArray], FloatArray],
    eps_m: float,
    n_sub: int,
    per_sub: int,
) -> tuple[I32Array, I32Array, I32Array]:
    """Return the swept tube as (x0 (npsi, m), n columns (npsi, m), y ranges (npsi, m, c, 2)).

    One box per sub-interval of per_sub samples, padded for the deviation and for the
    motion between samples, then the hull of their cells per x column.
    """
    m = inputs.shape[0]
    n_t = n_sub * per_sub
    dt = float(t[-1]) / (t.shape[0] - 1)  # the step of t (s), as linspace made it
    t_end = t[per_sub::per_sub]  # (n_sub,)
    dev = (rho(t_end) + eps_m)[None]  # (1, m, n_sub): true position, start uncertain by eps
    th_sub = theta(t_end)  # (n_sub,)
    sub = boxes[:, :, :n_t, :].reshape(grid.npsi, m, n_sub, per_sub, 4)
    last = boxes[:, :, per_sub::per_sub, :][:, :, :, None, :]  # closing sample of each span
    sub = np.concatenate([sub, last], axis=3)
    lo_x, hi_x = sub[..., 0].min(axis=3), sub[..., 1].max(axis=3)
    lo_y, hi_y = sub[..., 2].min(axis=3), sub[..., 3].max(axis=3)
    # World velocity direction over each span, for every psi0 in the cell: [lo, hi] (rad).
    beta = np.arctan2(inputs[:, 1], inputs[:, 0])[None, :, None]
    r = inputs[:, 2][None, :, None]
    t_start = t[:-1:per_sub][None, None, :]
    te = t_end[None, None, :]
    turn_lo = np.minimum(r * t_start, r * te) - th_sub[None, None, :]
    turn_hi = np.maximum(r * t_start, r * te) + th_sub[None, None, :]
    dir_lo = psi_lo[:, None, None] + beta + turn_lo
    dir_hi = psi_hi[:, None, None] + beta + turn_hi
    between = np.hypot(inputs[:, 0], inputs[:, 1])[None, :, None] * dt / 2.0
    pad_x = dev + np.where(_contains_angle(dir_lo, dir_hi, 0.5 * math.pi), between, 0.0)
    pad_y = dev + np.where(_contains_angle(dir_lo, dir_hi, 0.0), between, 0.0)
    bx0, bx1 = _offsets(lo_x - pad_x, hi_x + pad_x, grid.cell_x_m)
    by0, by1 = _offsets(lo_y - pad_y, hi_y + pad_y, grid.cell_y_m)
    tube_x0 = bx0.min(axis=2)
    tube_n = bx1.max(axis=2) - tube_x0 + 1
    return tube_x0.astype(np.int32), tube_n.astype(np.int32), _tube_columns(
        bx0, bx1, by0, by1, tube_x0, tube_n
    )


def _tube_columns(
    bx0: I32Array, bx1: I32Array, by0: I32Array, by1: I32Array, tube_x0: I32Array, tube_n: I32Array
) -> I32Array:
    """Return each tube column's y cell range, shape (npsi, m, c, 2), from the span boxes.

    b*: the span boxes' cell bounds, (npsi, m, n_sub); tube_x0, tube_n: the tube's first
    x column and column count, (npsi, m). Columns past a tube's end are 0 (never read).
    """
    c_max = int(tube_n.max())
    big = np.iinfo(np.int32).max
    tube_y = np.empty((*tube_x0.shape, c_max, 2), dtype=np.int32)
    for c in range(c_max):
        col = (tube_x0 + c)[..., None]
        covers = (bx0 <= col) & (col <= bx1)
        tube_y[..., c, 0] = np.where(covers, by0, big).min(axis=2)
        tube_y[..., c, 1] = np.where(covers, by1, -big).max(axis=2)
    unused = np.arange(c_max)[None, None, :] >= tube_n[..., None]
    tube_y[unused] = 0
    return tube_y


def _hull_headings(
    r_in: FloatArray, psi_lo: FloatArray, psi_hi: FloatArray, horizon_s: float, th_end: float
) -> FloatArray:
    """Return the headings the hull may take over the period, (npsi, n_yaw, 2) (rad).

    One [lo, hi] per heading cell (psi_lo, psi_hi (npsi,)) and distinct yaw rate of r_in.
    """
    yaw_values = np.unique(r_in)
    turn_all_lo = np.minimum(0.0, yaw_values * horizon_s) - th_end
    turn_all_hi = np.maximum(0.0, yaw_values * horizon_s) + th_end
    return np.stack(
        [
            psi_lo[:, None] + turn_all_lo[None, :],
            psi_hi[:, None] + turn_all_hi[None, :],
        ],
        axis=-1,
    )


def build_tables(
    grid: Grid,
    inputs: FloatArray,
    tau_s: float,
    budget: DeviationBudget,
    late_s: float = 0.0,
    n_sub: int = 16,
    per_sub: int = 4,
) -> Tables:
    """Compute the offset tables of both classes (no cache).

    Args:
        grid: The state grid.
        inputs: Inputs (u m/s, v m/s, r rad/s), shape (m, 3).
        tau_s: Command period (s).
        budget: Deviation from the exact arc per class, and the estimate's error.
        late_s: Extra time a command may be held (s); bounds hold up to tau + late.
        n_sub: Number of sub-intervals of [0, tau + late] in the swept tube.
        per_sub: Time samples per sub-interval (the padding shrinks with more).

    Raises:
        GridError: Inputs of the wrong shape, non-positive tau, negative late.
    """
    arr = _check_inputs(inputs, tau_s, late_s)
    horizon = tau_s + late_s
    eps_m = float(budget.estimation_position_m)
    eps_rad = float(budget.estimation_heading_rad)
    speed = np.hypot(arr[:, 0], arr[:, 1])
    per_class = []
    n_budget = int(budget.n_classes)
    for cls in range(N_CLASSES):
        # Each class contains the ones below it (a change is never budgeted below a
        # hold, a first command never below a change); a budget without a class of its
        # own for first commands lends them the change class.
        classes = tuple(range(min(cls, n_budget - 1) + 1))

        def rho(t: FloatArray, classes: tuple[int, ...] = classes) -> FloatArray:
            out: FloatArray = np.max(
                [budget.position_bound_m(c, speed, t) for c in classes], axis=0
            )
            return out

        def theta(t: FloatArray, classes: tuple[int, ...] = classes) -> FloatArray:
            out: FloatArray = np.max([budget.heading_bound_rad(c, t) for c in classes], axis=0)
            return out

        per_class.append(
            _class_tables(grid, arr, tau_s, horizon, rho, theta, eps_m, eps_rad, n_sub, per_sub)
        )
    c_max = max(pc.tube_y.shape[2] for pc in per_class)
    tube_y = np.zeros((N_CLASSES, grid.npsi, arr.shape[0], c_max, 2), dtype=np.int32)
    for cls, pc in enumerate(per_class):
        tube_y[cls, :, :, : pc.tube_y.shape[2]] = pc.tube_y
    yaw_values = np.unique(arr[:, 2])
    return Tables(
        grid=grid,
        inputs=arr,
        tau_s=float(tau_s),
        late_s=float(late_s),
        succ=np.ascontiguousarray(np.stack([pc.succ for pc in per_class])),
        heading=np.ascontiguousarray(np.stack([pc.heading for pc in per_class])),
        tube_x0=np.ascontiguousarray(np.stack([pc.tube_x0 for pc in per_class])),
        tube_n=np.ascontiguousarray(np.stack([pc.tube_n for pc in per_class])),
        tube_y=np.ascontiguousarray(tube_y),
        hull_psi=np.ascontiguousarray(np.stack([pc.hull_psi for pc in per_class])),
        yaw_index=np.searchsorted(yaw_values, arr[:, 2]).astype(np.int32),
        budget_key=budget.digest(),
        key=_key(grid, arr, tau_s, late_s, budget.digest(), n_sub),
    )


_TABLE_FIELDS = ("succ", "heading", "tube_x0", "tube_n", "tube_y", "hull_psi", "yaw_index")


def tables_for(
    grid: Grid,
    inputs: FloatArray,
    tau_s: float,
    budget: DeviationBudget,
    late_s: float = 0.0,
    cache_dir: Path | None = None,
    use_cache: bool = True,
) -> tuple[Tables, bool]:
    """Return the tables, loading them from the on-disk cache when present.

    Args:
        grid: The state grid.
        inputs: Inputs, shape (m, 3).
        tau_s: Command period (s).
        budget: The deviation budget.
        late_s: Extra time a command may be held (s).
        cache_dir: Cache folder; :func:`default_cache_dir` if None.
        use_cache: False computes fresh tables and writes nothing.

    Returns:
        The tables and whether they came from the cache.
    """
    arr = _check_inputs(inputs, tau_s, late_s)
    if not use_cache:
        return build_tables(grid, arr, tau_s, budget, late_s), False
    folder = default_cache_dir() if cache_dir is None else Path(cache_dir)
    key = _key(grid, arr, tau_s, late_s, budget.digest(), 16)
    path = folder / f"tables-{key}.npz"
    if path.is_file():
        try:
            with np.load(path) as data:
                fields = {name: data[name] for name in _TABLE_FIELDS}
                stored_key = str(data["key"])
            tables = Tables(
                grid=grid,
                inputs=arr,
                tau_s=float(tau_s),
                late_s=float(late_s),
                budget_key=budget.digest(),
                key=stored_key,
                **fields,
            )
            if tables.succ.shape == (N_CLASSES, grid.npsi, arr.shape[0], 4) and stored_key == key:
                return tables, True
        except (OSError, KeyError, ValueError, TypeError):
            pass  # a corrupt or stale cache entry is rebuilt below
    tables = build_tables(grid, arr, tau_s, budget, late_s)
    folder.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
    np.savez(tmp, key=np.array(tables.key), **{n: getattr(tables, n) for n in _TABLE_FIELDS})
    os.replace(tmp, path)
    return tables, False
