"""Free-cell masks that keep the whole hull clear, per range of headings.

The hull is the rectangle L x B centred on the body origin, its length along the body x
axis (:func:`hil.scenarios.scenario.hull_footprint`). At heading psi its axis-aligned
bounding box is centre + [-ex, ex] x [-ey, ey] with

    ex(psi) = L/2 |cos psi| + B/2 |sin psi|,    ey(psi) = L/2 |sin psi| + B/2 |cos psi|

(the rectangle's support function along x and y); :func:`hull_half_extents` gives their
exact maxima over a heading range. A cell is free for a range (:func:`free_masks`) when,
for every centre in the closed cell and every heading of the range:

- walls: the hull lies in the closed arena. The cell must lie in the arena shrunk by
  the range's (ex, ey); exact up to the cell quantization (a rectangle lies in a
  rectangle iff its bounding box does);
- obstacles: the hull misses every closed real obstacle (a rectangle or a convex
  polygon). First the box: only cells that meet the obstacle's bounding box grown by
  (ex, ey) can be blocked. Those are then tested by separating axes: the set of hull
  positions over the cell and the range lies, along any unit axis d, within the cell's
  projection grown by the hull's largest support along d over the range (exact, the
  same formula turned by the axis angle); if that interval misses the obstacle's
  projection on one axis, the cell is clear. Axes: the obstacle's edge normals, the
  hull's long and lateral axes at the middle of the range and the two diagonals. For a
  single heading (a range of width zero) these axes with x and y are all the edge
  normals of (cell + hull) and of the obstacle, so the test is exact; a wider range
  loses cells near obstacle corners (the union of the hull's positions over the range
  is not convex). Masks of sub-ranges, ANDed, are sound too and usually tighter;
- abstract obstacles: the centre is off every obstacle inflated by its inflation (the
  paper's rule, :func:`~hil.controllers.symbolic.grid.obstacle_mask` semantics).

Conventions are :mod:`~hil.controllers.symbolic.grid`'s: cells are closed boxes for
these tests; a cell within 1e-9 m (the grid's slack) of touching an obstacle counts as
touching it, and a cell sticking out of the shrunk arena by less than 1e-9 m counts as
inside (so rounding such as cos(pi / 2) = 6e-17 does not cost a row of cells; the hull
may then reach 1e-9 m past a wall).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hil.controllers.symbolic.errors import GridError
from hil.controllers.symbolic.grid import (
    _SLACK_M,
    Grid,
    _inside,
    _polygon_halfplanes,
    obstacle_mask,
)
from hil.core.arrays import BoolArray, FloatArray
from hil.core.jit import njit
from hil.core.shapes import Polygon, Rect, Shape

IntpArray = NDArray[np.intp]

__all__ = ["free_masks", "hull_half_extents", "target_cells"]

# Extra separating axes. The hull's long and lateral axes at the middle heading of each
# range: with x, y and the obstacle's normals they make the test exact for a single
# heading. The fixed diagonals: they cut the corners of the rounded region a turning
# hull sweeps (on the paper grid with obstacles inflated by 0.1 m, a full turn loses 16
# cells against 100 without them), and with x and y they make a cell free for a full
# turn free for every range.
_HULL_AXES_RAD = (0.0, 0.5 * math.pi)
_FIXED_AXES_RAD = (0.25 * math.pi, 0.75 * math.pi)


def _heading_ranges(psi_lo: ArrayLike, psi_hi: ArrayLike) -> tuple[FloatArray, FloatArray]:
    lo = np.asarray(psi_lo, dtype=np.float64)
    hi = np.asarray(psi_hi, dtype=np.float64)
    if lo.ndim != 1 or lo.shape != hi.shape:
        raise GridError(
            f"psi_lo and psi_hi must be 1-D of one shape, got {lo.shape!r} and {hi.shape!r}"
        )
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise GridError("heading ranges must be finite (NaN or inf in psi_lo or psi_hi)")
    bad = np.flatnonzero(lo > hi)
    if bad.size:
        h = int(bad[0])
        raise GridError(
            f"heading range {h} is reversed: psi_lo {float(lo[h])!r} > psi_hi {float(hi[h])!r}"
        )
    return lo, hi


def _contains(lo: FloatArray, hi: FloatArray, angle: float) -> BoolArray:
    """Return True where [lo, hi] holds angle + k pi for some integer k."""
    out: BoolArray = np.ceil((lo - angle) / math.pi) * math.pi + angle <= hi
    return out


def hull_half_extents(
    length_m: float, beam_m: float, psi_lo: ArrayLike, psi_hi: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Return the hull's largest axis-aligned half-extents over each heading range.

    For range h, ex[h] = max of L/2 |cos psi| + B/2 |sin psi| and ey[h] = max of
    L/2 |sin psi| + B/2 |cos psi| over psi in [psi_lo[h], psi_hi[h]]: the half-widths of
    the smallest axis-aligned box around the body origin holding the hull rectangle at
    every heading of the range. Ranges may have any width and need not be wrapped; one
    of width pi or more gives the half-diagonal on both axes.

    Args:
        length_m: Hull length along the body x axis (m), >= 0.
        beam_m: Hull beam (m), >= 0.
        psi_lo: Lower heading of each range (rad), shape (n,).
        psi_hi: Upper heading of each range (rad), shape (n,), >= psi_lo.

    Returns:
        (ex, ey) in m, each shape (n,).

    Raises:
        GridError: Non-finite or negative hull size; non-finite, reversed or
            mismatched heading ranges.

    Notes:
        Each of ex, ey is R cos(psi - theta) on the quarter turns between its kinks
        (multiples of pi/2), R = hypot(L/2, B/2): its maxima R lie at +-alpha + k pi for
        ex and pi/2 +- alpha + k pi for ey, alpha = atan2(B, L), and elsewhere the
        maximum is at an end of the range. So the maximum is exact: the larger end
        value, or R when the range holds a critical angle.
    """
    if not (math.isfinite(length_m) and math.isfinite(beam_m) and length_m >= 0 and beam_m >= 0):
        raise GridError(f"hull size must be finite and >= 0, got {(length_m, beam_m)!r}")
    lo, hi = _heading_ranges(psi_lo, psi_hi)
    a, b = 0.5 * length_m, 0.5 * beam_m
    radius = math.hypot(a, b)
    alpha = math.atan2(b, a)

    def along_x(psi: FloatArray) -> FloatArray:
        out: FloatArray = a * np.abs(np.cos(psi)) + b * np.abs(np.sin(psi))
        return out

    def along_y(psi: FloatArray) -> FloatArray:
        out: FloatArray = a * np.abs(np.sin(psi)) + b * np.abs(np.cos(psi))
        return out

    ex = np.maximum(along_x(lo), along_x(hi))
    ey = np.maximum(along_y(lo), along_y(hi))
    peak_x = _contains(lo, hi, alpha) | _contains(lo, hi, -alpha)
    peak_y = _contains(lo, hi, 0.5 * math.pi - alpha) | _contains(lo, hi, 0.5 * math.pi + alpha)
    # max() keeps an end value that rounding put a hair above the half-diagonal.
    ex = np.where(peak_x, np.maximum(ex, radius), ex)
    ey = np.where(peak_y, np.maximum(ey, radius), ey)
    return ex, ey


def _first_at_least(edges: FloatArray, bound: FloatArray) -> IntpArray:
    """Return, per bound, the first index i with edges[i] >= bound (len(edges) if none)."""
    out: IntpArray = np.searchsorted(edges, bound, side="left")
    return out


def _count_at_most(edges: FloatArray, bound: FloatArray) -> IntpArray:
    """Return, per bound, how many edges are <= bound (edges ascending)."""
    out: IntpArray = np.searchsorted(edges, bound, side="right")
    return out


def _blocked_span(
    edges: FloatArray, lo_m: float, hi_m: float, grow_m: FloatArray
) -> tuple[IntpArray, IntpArray]:
    """Return cells [start, stop) per range whose closed extent meets [lo - grow, hi + grow].

    `edges` are the cell edges (nc + 1,); cell i spans [edges[i], edges[i + 1]]. A cell
    within the grid's slack of the grown interval counts as meeting it.
    """
    start = _first_at_least(edges[1:], lo_m - grow_m - _SLACK_M)
    stop = _count_at_most(edges[:-1], hi_m + grow_m + _SLACK_M)
    return start, stop


def _check_shape(shape: Shape, what: str) -> None:
    v = shape.vertices()
    if not np.all(np.isfinite(v)):
        raise GridError(f"{what} has non-finite vertices: {shape!r}")
    if isinstance(shape, Rect):
        if shape.x_max_m < shape.x_min_m or shape.y_max_m < shape.y_min_m:
            raise GridError(f"{what} is an inverted rectangle: {shape!r}")
    elif shape.is_empty():
        raise GridError(f"{what} must be a convex counter-clockwise polygon: {shape!r}")


def _inflations(obstacles: Sequence[Shape], inflation_m: float | Sequence[float]) -> list[float]:
    if isinstance(inflation_m, (int, float)):
        given = [float(inflation_m)]
        out = given * len(obstacles)
    else:
        given = out = [float(m) for m in inflation_m]
        if len(out) != len(obstacles):
            raise GridError(f"{len(out)} inflations for {len(obstacles)} obstacles")
    for m in given:
        if not (math.isfinite(m) and m >= 0.0):
            raise GridError(f"obstacle inflation must be finite and >= 0, got {m!r}")
    return out


@njit
def _clear_touching(
    out: BoolArray,
    xs: FloatArray,
    ys: FloatArray,
    spans: NDArray[np.int64],
    axes: FloatArray,
    reach: FloatArray,
    shadow: FloatArray,
    slack_m: float,
) -> None:
    """Clear, in place, the cells whose grown cell may touch one obstacle.

    Only cells in the range's span (those the x and y axes cannot separate) are visited;
    each is cleared unless one of the extra axes separates it.

    Args:
        out: Free cells, shape (n, nx, ny), indexed [range, i, j]; updated.
        xs: Cell edges in x (m), shape (nx + 1,).
        ys: Cell edges in y (m), shape (ny + 1,).
        spans: Cells [i0, i1) x [j0, j1) to visit per range, shape (n, 4).
        axes: Unit axes per range, shape (n, K, 2).
        reach: Half-width of the cell grown by the hull along each axis (m), (n, K).
        shadow: The obstacle's projection (min, max) on each axis (m), (n, K, 2).
        slack_m: A gap of at most this counts as touching (m).
    """
    n_ranges, n_axes = reach.shape
    for h in range(n_ranges):
        for i in range(spans[h, 0], spans[h, 1]):
            cx = 0.5 * (xs[i] + xs[i + 1])
            for j in range(spans[h, 2], spans[h, 3]):
                if not out[h, i, j]:
                    continue
                cy = 0.5 * (ys[j] + ys[j + 1])
                apart = False
                for k in range(n_axes):
                    p = axes[h, k, 0] * cx + axes[h, k, 1] * cy
                    r = reach[h, k]
                    if p - r > shadow[h, k, 1] + slack_m or p + r < shadow[h, k, 0] - slack_m:
                        apart = True
                        break
                if not apart:
                    out[h, i, j] = False


def _separating_axes(
    grid: Grid,
    shape: Shape,
    length_m: float,
    beam_m: float,
    lo: FloatArray,
    hi: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Return the extra axes for one obstacle: (axes (n, K, 2), reach (n, K), shadow (n, K, 2)).

    The axes are the hull's own at the middle of each range (long and lateral), the two
    diagonals of the arena frame, and the obstacle's edge normals that are not x or y.
    Along an axis at angle theta the hull reaches max over the range of
    L/2 |cos(psi - theta)| + B/2 |sin(psi - theta)|, exactly :func:`hull_half_extents`
    of the range turned by -theta; the cell reaches half its width along the axis.
    """
    v = shape.vertices()
    mid = 0.5 * (lo + hi)
    axes: list[FloatArray] = []
    hull: list[FloatArray] = []
    for theta in [mid + a for a in _HULL_AXES_RAD] + [
        np.full_like(mid, a) for a in _FIXED_AXES_RAD
    ]:
        axes.append(np.stack([np.cos(theta), np.sin(theta)], axis=1))
        hull.append(hull_half_extents(length_m, beam_m, lo - theta, hi - theta)[0])
    if isinstance(shape, Polygon):
        normals, _ = _polygon_halfplanes(v)
        for nx_, ny_ in normals:
            if abs(nx_) < 1e-12 or abs(ny_) < 1e-12:
                continue  # x or y: the spans already test it
            angle = math.atan2(ny_, nx_)
            axes.append(np.broadcast_to(np.array([nx_, ny_]), (lo.shape[0], 2)))
            hull.append(hull_half_extents(length_m, beam_m, lo - angle, hi - angle)[0])
    ax = np.ascontiguousarray(np.stack(axes, axis=1))  # (n, K, 2)
    cell = 0.5 * (grid.cell_x_m * np.abs(ax[..., 0]) + grid.cell_y_m * np.abs(ax[..., 1]))
    reach = np.ascontiguousarray(np.stack(hull, axis=1) + cell)
    proj = np.einsum("hkc,vc->hkv", ax, v)
    shadow = np.ascontiguousarray(np.stack([proj.min(axis=2), proj.max(axis=2)], axis=2))
    return ax, reach, shadow


def free_masks(
    grid: Grid,
    obstacles: Sequence[Shape],
    arena: Rect,
    inflation_m: float | Sequence[float],
    length_m: float,
    beam_m: float,
    psi_lo: ArrayLike,
    psi_hi: ArrayLike,
) -> BoolArray:
    """Return which cells keep the hull clear for every heading of each range.

    Cell (i, j), a closed box of the grid, is free for range h when, for every centre in
    it and every heading in [psi_lo[h], psi_hi[h]], the hull rectangle lies in the
    closed arena and misses every (closed) real obstacle, and the centre lies outside
    every obstacle inflated by its inflation. Sound with the slack the module docstring
    states; see it for where the test is exact.

    Args:
        grid: The state grid (its x, y cells; headings come from the ranges).
        obstacles: Real obstacles in (x, y): rectangles or convex polygons.
        arena: The arena the whole hull must stay in.
        inflation_m: Inflation of the abstract obstacles (m), one for all or one per
            obstacle; the centre must stay off the inflated obstacles.
        length_m: Hull length along the body x axis (m).
        beam_m: Hull beam (m).
        psi_lo: Lower heading of each range (rad), shape (n,).
        psi_hi: Upper heading of each range (rad), shape (n,), >= psi_lo.

    Returns:
        Bool array shape (n, nx, ny), indexed [range, i, j]: True where free.

    Raises:
        GridError: Bad heading ranges or hull size (see :func:`hull_half_extents`), a
            negative or non-finite inflation, a non-finite, inverted or non-convex
            obstacle or arena.
    """
    lo, hi = _heading_ranges(psi_lo, psi_hi)
    ex, ey = hull_half_extents(length_m, beam_m, lo, hi)
    _check_shape(arena, "arena")
    for k, shape in enumerate(obstacles):
        _check_shape(shape, f"obstacle {k}")
    margins = _inflations(obstacles, inflation_m)

    # Centre off the inflated obstacles: the same for every range.
    static = ~obstacle_mask(grid, [s.inflate(m) for s, m in zip(obstacles, margins, strict=True)])
    xs, ys = grid._edges()
    # Walls: the cell must lie in the arena shrunk by (ex, ey).
    wx0 = _first_at_least(xs[:-1], arena.x_min_m + ex - _SLACK_M)
    wx1 = _count_at_most(xs[1:], arena.x_max_m - ex + _SLACK_M)
    wy0 = _first_at_least(ys[:-1], arena.y_min_m + ey - _SLACK_M)
    wy1 = _count_at_most(ys[1:], arena.y_max_m - ey + _SLACK_M)
    n = ex.shape[0]
    out: BoolArray = np.zeros((n, grid.nx, grid.ny), dtype=bool)
    walls = np.stack([wx0, wx1, wy0, wy1], axis=1).tolist()
    for h in range(n):
        a0, a1, b0, b1 = walls[h]
        out[h, a0:a1, b0:b1] = static[a0:a1, b0:b1]
    for shape in obstacles:
        v = shape.vertices()
        spans = np.stack(
            [
                *_blocked_span(xs, float(v[:, 0].min()), float(v[:, 0].max()), ex),
                *_blocked_span(ys, float(v[:, 1].min()), float(v[:, 1].max()), ey),
            ],
            axis=1,
        ).astype(np.int64)
        axes, reach, shadow = _separating_axes(grid, shape, length_m, beam_m, lo, hi)
        _clear_touching(out, xs, ys, spans, axes, reach, shadow, _SLACK_M)
    return out


def target_cells(grid: Grid, target: Shape, free: BoolArray) -> BoolArray:
    """Return the cells wholly inside the (abstract) target and free for each range.

    Args:
        grid: The state grid.
        target: The abstract (deflated) target in (x, y).
        free: Free cells per heading range, shape (n, nx, ny) (:func:`free_masks`).

    Returns:
        Bool array shape (n, nx, ny), indexed [range, i, j].

    Raises:
        GridError: `free` has the wrong shape.
    """
    if free.ndim != 3 or free.shape[1:] != (grid.nx, grid.ny):
        raise GridError(f"free mask shape {free.shape!r} != (n, {grid.nx}, {grid.ny})")
    out: BoolArray = _inside(grid, target)[None, :, :] & free
    return out
