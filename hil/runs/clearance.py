"""Hull clearance along a whole trajectory, vectorized over time.

The summary judges every physics step of a run (18,000 for three minutes), so
the distance between the hull rectangle and each real obstacle is computed for
all poses at once: separating-axis test for contact, else the least
vertex-to-edge distance both ways (exact for convex polygons).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hil.core.arrays import FloatArray
from hil.core.shapes import Shape
from hil.scenarios import Scenario


def hull_corners(length_m: float, beam_m: float, eta: FloatArray) -> FloatArray:
    """Return the hull rectangle's corners at poses `eta` (N, 3): shape (N, 4, 2)."""
    half = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]], dtype=np.float64) * [
        length_m / 2, beam_m / 2]
    c, s = np.cos(eta[:, 2]), np.sin(eta[:, 2])
    x = eta[:, None, 0] + c[:, None] * half[None, :, 0] - s[:, None] * half[None, :, 1]
    y = eta[:, None, 1] + s[:, None] * half[None, :, 0] + c[:, None] * half[None, :, 1]
    return np.stack([x, y], axis=2)


def _edges(poly: FloatArray) -> FloatArray:
    return np.roll(poly, -1, axis=-2) - poly


def _overlap(hulls: FloatArray, obstacle: FloatArray) -> NDArray[np.bool_]:
    """Separating-axis test: (N, 4, 2) hulls against one convex (M, 2) polygon -> (N,)."""
    touching = np.ones(len(hulls), dtype=bool)
    hull_axes = _edges(hulls)[..., ::-1] * [1, -1]  # (N, 4, 2) edge normals
    obstacle_axes = _edges(obstacle)[:, ::-1] * [1, -1]  # (M, 2)
    axes = np.concatenate([hull_axes, np.broadcast_to(obstacle_axes,
                                                      (len(hulls), *obstacle_axes.shape))], 1)
    ph = np.einsum("nvd,nad->nav", hulls, axes)  # (N, A, 4)
    po = np.einsum("md,nad->nam", obstacle, axes)  # (N, A, M)
    apart = (ph.min(axis=2) > po.max(axis=2)) | (po.min(axis=2) > ph.max(axis=2))
    touching &= ~apart.any(axis=1)
    return touching


def _point_to_segments(points: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """Least distance from each of points (..., P, 2) to segments a->b (..., S, 2): (...,)."""
    ab = b - a  # (..., S, 2)
    ap = points[..., :, None, :] - a[..., None, :, :]  # (..., P, S, 2)
    denom = np.maximum(np.sum(ab * ab, axis=-1), 1e-300)[..., None, :]
    t = np.clip(np.sum(ap * ab[..., None, :, :], axis=-1) / denom, 0.0, 1.0)
    closest = a[..., None, :, :] + t[..., None] * ab[..., None, :, :]
    d = np.linalg.norm(points[..., :, None, :] - closest, axis=-1)
    return np.asarray(d.min(axis=(-2, -1)))


def distance_to_shape(hulls: FloatArray, shape: Shape) -> FloatArray:
    """Return the distance from each hull (N, 4, 2) to a convex shape (m), 0 on contact."""
    obstacle = shape.vertices()
    n = len(hulls)
    ob = np.broadcast_to(obstacle, (n, *obstacle.shape))
    d_hull = _point_to_segments(hulls, ob, np.roll(ob, -1, axis=1))
    d_obstacle = _point_to_segments(ob, hulls, np.roll(hulls, -1, axis=1))
    out = np.minimum(d_hull, d_obstacle)
    out[_overlap(hulls, obstacle)] = 0.0
    return out


def hull_clearance_series(scenario: Scenario, eta: FloatArray,
                          offsets_m: FloatArray | None = None) -> FloatArray:
    """Return the hull's distance to the nearest real obstacle at each pose (N, 3) -> (N,).

    Args:
        scenario: Real obstacles (where they are at t = 0) and the hull.
        eta: Poses (x m, y m, psi rad), shape (N, 3).
        offsets_m: Each obstacle's displacement from its scenario position at each pose's
            time (m), shape (n_obstacles, N, 2) (:func:`~hil.core.motion.displacements_m`);
            None: the obstacles stay where the scenario puts them.

    Returns:
        Distances (m), shape (N,): zero means contact or overlap; inf without obstacles.
    """
    eta = np.asarray(eta, dtype=np.float64).reshape(-1, 3)
    out = np.full(len(eta), np.inf)
    for index, obstacle in enumerate(scenario.obstacles):
        rel = eta
        if offsets_m is not None and np.any(offsets_m[index]):
            # Judge in the obstacle's frame: move the vessel back by the obstacle's motion.
            rel = eta.copy()
            rel[:, :2] -= offsets_m[index]
        hulls = hull_corners(scenario.hull.length_m, scenario.hull.beam_m, rel)
        out = np.minimum(out, distance_to_shape(hulls, obstacle.shape))
    return out


def hull_margin_series(scenario: Scenario, eta: FloatArray) -> FloatArray:
    """Return the hull's least clearance to the real obstacles and the walls (N, 3) -> (N,).

    Args:
        scenario: Real obstacles (where the scenario places them), the arena and the hull.
        eta: Poses (x m, y m, psi rad), shape (N, 3).

    Returns:
        Clearances (m), shape (N,): the smaller of the distance to the nearest obstacle
        (0 on contact) and the distance from the hull's corners to the nearest wall
        (negative: a corner past a wall).
    """
    eta = np.asarray(eta, dtype=np.float64).reshape(-1, 3)
    obstacles = hull_clearance_series(scenario, eta)
    hulls = hull_corners(scenario.hull.length_m, scenario.hull.beam_m, eta)
    (x0, x1), (y0, y1) = scenario.x_range_m, scenario.y_range_m
    walls = np.minimum.reduce([
        hulls[..., 0].min(axis=1) - x0, x1 - hulls[..., 0].max(axis=1),
        hulls[..., 1].min(axis=1) - y0, y1 - hulls[..., 1].max(axis=1),
    ])  # fmt: skip
    out: FloatArray = np.minimum(obstacles, walls)
    return out
