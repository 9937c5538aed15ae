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
- With a tracking-error margin m = (m_u, m_v, m_r) on |nu - nu_ref|, the heading error
  grows at most m_r t and the position error at most
  rho(t) = |(m_u, m_v)| t + |(u, v)| m_r t^2 / 2
  (|R(a) - R(b)| <= |a - b|), added to every box up to the end of its span.
- Half-open cells: a displacement interval [lo, hi] reaches cell offsets
  floor(lo / h) .. ceil(hi / h); the heading offset interval likewise. Bounds within
  1e-9 cell widths of a cell edge (5e-11 m on the paper grid) snap to it, so that
  rounding (cos(pi / 2) = 6e-17) does not add a whole row of cells.
"""

from __future__ import annotations

import hashlib
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.errors import GridError
from hil.controllers.symbolic.grid import Grid

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int32]

__all__ = [
    "Tables",
    "build_tables",
    "default_cache_dir",
    "displacement",
    "tables_for",
]

_VERSION = 2
_SNAP = 1e-9  # cell widths: bounds this close to a cell edge snap onto it


def default_cache_dir() -> Path:
    """Return $HIL_CACHE_DIR, else ~/.cache/hil/symbolic."""
    env = os.environ.get("HIL_CACHE_DIR")
    return Path(env) if env else Path.home() / ".cache" / "hil" / "symbolic"


@dataclass(frozen=True, slots=True, eq=False)
class Tables:
    """Cell-offset tables of one grid, input set, tau and margin.

    Attributes:
        grid: The state grid.
        inputs: Inputs (surge m/s, sway m/s, yaw rate rad/s), shape (m, 3).
        tau_s: Sampling time (s).
        margin: Tracking-error margin (surge, sway, yaw rate), shape (3,).
        succ: Successor offset boxes, shape (npsi, m, 4) indexed [k, input]:
            (ox_min, ox_max, oy_min, oy_max) in cells, inclusive.
        heading: Successor heading offsets, shape (m, 2): (ok_min, ok_max), inclusive;
            the same for every heading cell.
        tube_x0: First x offset of the swept tube, shape (npsi, m).
        tube_n: Number of tube columns, shape (npsi, m).
        tube_y: Tube column y ranges, shape (npsi, m, c_max, 2): column c is
            x offset tube_x0 + c with y offsets tube_y[..., c, 0] .. tube_y[..., c, 1].
        key: Hash of everything the tables depend on.
    """

    grid: Grid
    inputs: FloatArray
    tau_s: float
    margin: FloatArray
    succ: IntArray
    heading: IntArray
    tube_x0: IntArray
    tube_n: IntArray
    tube_y: IntArray
    key: str

    @property
    def n_inputs(self) -> int:
        """Return the number of inputs m."""
        return int(self.inputs.shape[0])

    def nbytes(self) -> int:
        """Return the memory the tables hold (bytes)."""
        return sum(
            a.nbytes for a in (self.succ, self.heading, self.tube_x0, self.tube_n, self.tube_y)
        )


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


def _offsets(lo: FloatArray, hi: FloatArray, width: float) -> tuple[IntArray, IntArray]:
    return (
        np.floor(lo / width + _SNAP).astype(np.int32),
        np.ceil(hi / width - _SNAP).astype(np.int32),
    )


def _contains_angle(lo: FloatArray, hi: FloatArray, angle: float) -> NDArray[np.bool_]:
    """Return True where [lo, hi] contains angle + n pi for some integer n."""
    return np.asarray(np.ceil((lo - angle) / math.pi) * math.pi + angle <= hi, dtype=bool)


def _heading_offsets(shift_cells: FloatArray, lower: bool) -> IntArray:
    # A shift that is an integer up to rounding moves the cell onto cells exactly.
    nearest = np.round(shift_cells)
    exact = np.abs(shift_cells - nearest) < 1e-9
    bound = np.floor(shift_cells) if lower else np.ceil(shift_cells)
    return np.where(exact, nearest, bound).astype(np.int32)


def _key(
    grid: Grid, inputs: FloatArray, tau_s: float, margin: FloatArray, n_sub: int, per_sub: int
) -> str:
    h = hashlib.sha256()
    h.update(repr((_VERSION, grid.digest(), tau_s, n_sub, per_sub)).encode())
    h.update(np.ascontiguousarray(inputs, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(margin, dtype=np.float64).tobytes())
    return h.hexdigest()[:20]


def build_tables(
    grid: Grid,
    inputs: FloatArray,
    tau_s: float,
    margin: FloatArray | None = None,
    n_sub: int = 16,
    per_sub: int = 4,
) -> Tables:
    """Compute the offset tables (no cache).

    Args:
        grid: The state grid.
        inputs: Inputs (u m/s, v m/s, r rad/s), shape (m, 3).
        tau_s: Sampling time (s).
        margin: Tracking-error bound (u, v, r), shape (3,); zeros if None.
        n_sub: Number of sub-intervals of [0, tau] in the swept tube.
        per_sub: Time samples per sub-interval (the padding shrinks with more).

    Raises:
        GridError: Inputs of the wrong shape, non-positive tau, negative margin.
    """
    inputs = np.ascontiguousarray(inputs, dtype=np.float64)
    m_arr = np.zeros(3) if margin is None else np.asarray(margin, dtype=np.float64).reshape(3)
    if (
        inputs.ndim != 2
        or inputs.shape[1] != 3
        or inputs.shape[0] == 0
        or not np.all(np.isfinite(inputs))
    ):
        raise GridError(f"inputs must be a finite (m, 3) array, got shape {inputs.shape!r}")
    if not (math.isfinite(tau_s) and tau_s > 0.0):
        raise GridError(f"tau_s must be positive, got {tau_s!r}")
    if np.any(m_arr < 0.0) or not np.all(np.isfinite(m_arr)):
        raise GridError(f"margin must be finite and >= 0, got {m_arr!r}")
    hp = grid.heading_cell_rad
    psi_lo = np.asarray(-math.pi + hp * np.arange(grid.npsi), dtype=np.float64)
    psi_hi = psi_lo + hp
    n_t = n_sub * per_sub
    t = np.linspace(0.0, tau_s, n_t + 1)
    dt = tau_s / n_t
    speed = np.hypot(inputs[:, 0], inputs[:, 1])  # (m,)
    m_lin = math.hypot(m_arr[0], m_arr[1])

    def deviation(t_end: float) -> FloatArray:
        out: FloatArray = m_lin * t_end + speed * m_arr[2] * t_end**2 / 2.0  # (m,)
        return out

    boxes = _arc_boxes(displacement(inputs, t), psi_lo, psi_hi)  # (npsi, m, T, 4)

    # Successor box at tau.
    end = boxes[:, :, -1, :]
    pad_end = deviation(tau_s)[None, :]
    sx0, sx1 = _offsets(end[..., 0] - pad_end, end[..., 1] + pad_end, grid.cell_x_m)
    sy0, sy1 = _offsets(end[..., 2] - pad_end, end[..., 3] + pad_end, grid.cell_y_m)
    succ = np.stack([sx0, sx1, sy0, sy1], axis=-1).astype(np.int32)
    heading = np.stack(
        [
            _heading_offsets((inputs[:, 2] - m_arr[2]) * tau_s / hp, lower=True),
            _heading_offsets((inputs[:, 2] + m_arr[2]) * tau_s / hp, lower=False),
        ],
        axis=-1,
    ).astype(np.int32)

    # Swept tube: one box per sub-interval, then the hull of their cells per x column.
    sub = boxes.reshape(grid.npsi, inputs.shape[0], -1, 4)[:, :, :n_t, :]
    sub = sub.reshape(grid.npsi, inputs.shape[0], n_sub, per_sub, 4)
    last = boxes[:, :, per_sub::per_sub, :][:, :, :, None, :]  # closing sample of each span
    sub = np.concatenate([sub, last], axis=3)
    lo_x, hi_x = sub[..., 0].min(axis=3), sub[..., 1].max(axis=3)
    lo_y, hi_y = sub[..., 2].min(axis=3), sub[..., 3].max(axis=3)
    t_end = t[per_sub::per_sub]  # (n_sub,)
    # World velocity direction over each span, for every psi0 in the cell: [lo, hi] (rad).
    beta = np.arctan2(inputs[:, 1], inputs[:, 0])[None, :, None]
    r = inputs[:, 2][None, :, None]
    t_start = t[:-1:per_sub][None, None, :]
    turn_lo = np.minimum(r * t_start, r * t_end[None, None, :]) - m_arr[2] * t_end[None, None, :]
    turn_hi = np.maximum(r * t_start, r * t_end[None, None, :]) + m_arr[2] * t_end[None, None, :]
    dir_lo = psi_lo[:, None, None] + beta + turn_lo
    dir_hi = psi_hi[:, None, None] + beta + turn_hi
    dev = np.stack([deviation(te) for te in t_end], axis=-1)[None]  # (1, m, n_sub)
    between = speed[None, :, None] * dt / 2.0
    pad_x = dev + np.where(_contains_angle(dir_lo, dir_hi, 0.5 * math.pi), between, 0.0)
    pad_y = dev + np.where(_contains_angle(dir_lo, dir_hi, 0.0), between, 0.0)
    bx0, bx1 = _offsets(lo_x - pad_x, hi_x + pad_x, grid.cell_x_m)
    by0, by1 = _offsets(lo_y - pad_y, hi_y + pad_y, grid.cell_y_m)
    tube_x0 = bx0.min(axis=2)
    tube_n = bx1.max(axis=2) - tube_x0 + 1
    c_max = int(tube_n.max())
    big = np.iinfo(np.int32).max
    tube_y = np.empty((grid.npsi, inputs.shape[0], c_max, 2), dtype=np.int32)
    for c in range(c_max):
        col = (tube_x0 + c)[..., None]
        covers = (bx0 <= col) & (col <= bx1)
        tube_y[..., c, 0] = np.where(covers, by0, big).min(axis=2)
        tube_y[..., c, 1] = np.where(covers, by1, -big).max(axis=2)
    # Columns past a tube's end are never read; keep them harmless.
    unused = np.arange(c_max)[None, None, :] >= tube_n[..., None]
    tube_y[unused] = 0
    return Tables(
        grid=grid,
        inputs=inputs,
        tau_s=float(tau_s),
        margin=m_arr,
        succ=np.ascontiguousarray(succ),
        heading=np.ascontiguousarray(heading),
        tube_x0=np.ascontiguousarray(tube_x0.astype(np.int32)),
        tube_n=np.ascontiguousarray(tube_n.astype(np.int32)),
        tube_y=np.ascontiguousarray(tube_y),
        key=_key(grid, inputs, tau_s, m_arr, n_sub, per_sub),
    )


def tables_for(
    grid: Grid,
    inputs: FloatArray,
    tau_s: float,
    margin: FloatArray | None = None,
    cache_dir: Path | None = None,
    use_cache: bool = True,
) -> tuple[Tables, bool]:
    """Return the tables, loading them from the on-disk cache when present.

    Args:
        grid: The state grid.
        inputs: Inputs, shape (m, 3).
        tau_s: Sampling time (s).
        margin: Tracking-error bound, shape (3,), or None for zeros.
        cache_dir: Cache folder; :func:`default_cache_dir` if None.
        use_cache: False computes fresh tables and writes nothing.

    Returns:
        The tables and whether they came from the cache.
    """
    m_arr = np.zeros(3) if margin is None else np.asarray(margin, dtype=np.float64).reshape(3)
    inputs = np.ascontiguousarray(inputs, dtype=np.float64)
    if not use_cache:
        return build_tables(grid, inputs, tau_s, m_arr), False
    folder = default_cache_dir() if cache_dir is None else Path(cache_dir)
    path = folder / f"tables-{_key(grid, inputs, tau_s, m_arr, 16, 4)}.npz"
    if path.is_file():
        try:
            with np.load(path) as data:
                tables = Tables(
                    grid=grid,
                    inputs=inputs,
                    tau_s=float(tau_s),
                    margin=m_arr,
                    succ=data["succ"],
                    heading=data["heading"],
                    tube_x0=data["tube_x0"],
                    tube_n=data["tube_n"],
                    tube_y=data["tube_y"],
                    key=str(data["key"]),
                )
            if tables.succ.shape == (grid.npsi, inputs.shape[0], 4) and tables.key == path.stem[7:]:
                return tables, True
        except (OSError, KeyError, ValueError):
            pass  # a corrupt or stale cache entry is rebuilt below
    tables = build_tables(grid, inputs, tau_s, m_arr)
    folder.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
    np.savez(
        tmp,
        succ=tables.succ,
        heading=tables.heading,
        tube_x0=tables.tube_x0,
        tube_n=tables.tube_n,
        tube_y=tables.tube_y,
        key=np.array(tables.key),
    )
    os.replace(tmp, path)
    return tables, False
