"""Convex planar shapes in the arena frame: rectangles, polygons, distance and overlap.

Shapes are closed convex sets with lengths in metres: axis-aligned rectangles
(:class:`Rect`, also the obstacle rectangles of an
:class:`~hil.core.samples.ObstacleLayout`) or convex polygons (:class:`Polygon`,
e.g. a rotated rectangle). Inflating a polygon pushes every edge out by the
margin, which contains the Minkowski sum with a disc of that radius.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hil.core.arrays import FloatArray

__all__ = [
    "Polygon",
    "Rect",
    "Shape",
    "convex_distance_m",
    "shapes_overlap",
]

_EPS = 1e-9


@dataclass(frozen=True, slots=True)
class Rect:
    """An axis-aligned closed rectangle [x_min, x_max] x [y_min, y_max] (m).

    A rectangle may be empty (a target deflated too far); :meth:`is_empty` says so,
    and an :class:`~hil.core.samples.ObstacleLayout` refuses empty or non-finite ones.

    Attributes:
        x_min_m: Lower x bound (m).
        x_max_m: Upper x bound (m).
        y_min_m: Lower y bound (m).
        y_max_m: Upper y bound (m).
    """

    x_min_m: float
    x_max_m: float
    y_min_m: float
    y_max_m: float

    def vertices(self) -> FloatArray:
        """Return the corners counter-clockwise, shape (4, 2), columns (x, y) in m."""
        return np.array(
            [
                [self.x_min_m, self.y_min_m],
                [self.x_max_m, self.y_min_m],
                [self.x_max_m, self.y_max_m],
                [self.x_min_m, self.y_max_m],
            ]
        )

    def inflate(self, margin_m: float) -> Rect:
        """Return the rectangle grown by `margin_m` on every side (shrunk if negative)."""
        return Rect(
            self.x_min_m - margin_m,
            self.x_max_m + margin_m,
            self.y_min_m - margin_m,
            self.y_max_m + margin_m,
        )

    def translate(self, dx_m: float, dy_m: float) -> Rect:
        """Return the rectangle moved by (dx, dy) (m)."""
        return Rect(
            self.x_min_m + dx_m, self.x_max_m + dx_m, self.y_min_m + dy_m, self.y_max_m + dy_m
        )

    def is_empty(self) -> bool:
        """Return True when the rectangle has no area."""
        return not (self.x_max_m > self.x_min_m and self.y_max_m > self.y_min_m)


@dataclass(frozen=True, slots=True)
class Polygon:
    """A closed convex polygon; `vertices_m` counter-clockwise ((x, y) pairs in m)."""

    vertices_m: tuple[tuple[float, float], ...]

    @staticmethod
    def rotated_rect(
        center_m: tuple[float, float], size_m: tuple[float, float], angle_rad: float
    ) -> Polygon:
        """Return the rectangle of `size_m` (length along its x, width) turned by `angle_rad`."""
        half_l, half_w = 0.5 * size_m[0], 0.5 * size_m[1]
        c, s = math.cos(angle_rad), math.sin(angle_rad)
        corners = [(-half_l, -half_w), (half_l, -half_w), (half_l, half_w), (-half_l, half_w)]
        return Polygon(
            tuple((center_m[0] + c * a - s * b, center_m[1] + s * a + c * b) for a, b in corners)
        )

    def vertices(self) -> FloatArray:
        """Return the vertices counter-clockwise, shape (n, 2), columns (x, y) in m."""
        return np.asarray(self.vertices_m, dtype=np.float64)

    def inflate(self, margin_m: float) -> Polygon:
        """Return the polygon with every edge pushed out by `margin_m` (in if negative)."""
        v = self.vertices()
        n = len(v)
        edges = np.roll(v, -1, axis=0) - v
        normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1)
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        offset = np.sum(normals * v, axis=1) + margin_m
        out = []
        for a in range(n):
            b = (a - 1) % n  # vertex a joins edge b (into a) and edge a (out of a)
            m = np.array([normals[b], normals[a]])
            out.append(tuple(float(c) for c in np.linalg.solve(m, [offset[b], offset[a]])))
        return Polygon(tuple((p[0], p[1]) for p in out))

    def translate(self, dx_m: float, dy_m: float) -> Polygon:
        """Return the polygon moved by (dx, dy) (m)."""
        return Polygon(tuple((x + dx_m, y + dy_m) for x, y in self.vertices_m))

    def is_empty(self) -> bool:
        """Return True unless the polygon is convex, counter-clockwise and has area."""
        v = self.vertices()
        if len(v) < 3:
            return True
        edges = np.roll(v, -1, axis=0) - v
        nxt = np.roll(edges, -1, axis=0)
        cross = edges[:, 0] * nxt[:, 1] - edges[:, 1] * nxt[:, 0]
        return bool(np.any(cross <= 0.0))


Shape = Rect | Polygon


def _separated(a: FloatArray, b: FloatArray, gap_m: float) -> bool:
    """Return True when convex polygons a, b ((n, 2) each) are apart by more than gap_m."""
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1)
        norms = np.linalg.norm(normals, axis=1)
        for n, length in zip(normals, norms, strict=True):
            if length == 0.0:
                continue
            unit = n / length
            pa, pb = a @ unit, b @ unit
            if pa.min() > pb.max() + gap_m or pb.min() > pa.max() + gap_m:
                return True
    return False


def _point_segment_m(p: FloatArray, a: FloatArray, b: FloatArray) -> float:
    ab = b - a
    t = float(np.clip(np.dot(p - a, ab) / max(float(np.dot(ab, ab)), 1e-300), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * ab)))


def convex_distance_m(a: Shape, b: Shape) -> float:
    """Return the Euclidean distance between two convex shapes (m); 0 when they touch."""
    va, vb = a.vertices(), b.vertices()
    if not _separated(va, vb, 0.0):
        return 0.0
    best = math.inf
    for p_set, q_set in ((va, vb), (vb, va)):
        for p in p_set:
            for k in range(len(q_set)):
                best = min(best, _point_segment_m(p, q_set[k], q_set[(k + 1) % len(q_set)]))
    return best


def shapes_overlap(a: Shape, b: Shape) -> bool:
    """Return True when two convex shapes share interior points (touching is not overlap)."""
    return not _separated(a.vertices(), b.vertices(), -_EPS)
