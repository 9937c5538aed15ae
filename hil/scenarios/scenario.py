"""Docking scenarios: the arena, the grid, the inputs and the sets, read from TOML.

A scenario is a frozen description of one reach-avoid problem in the arena frame
(x, y in metres, heading psi in radians wrapped to [-pi, pi)). It keeps both the
real obstacles (for hull clearance at run time) and the abstract sets the
controller is synthesized for (obstacles inflated, target deflated; PAPER.md,
Fig. 3). Packaged scenarios live in `hil/scenarios/*.toml`; `load_scenario("paper")`
finds one by name, any other argument is read as a path.

Shapes are closed convex sets: axis-aligned rectangles (`Rect`) or convex polygons
(`Polygon`, e.g. a rotated rectangle). Inflating a polygon pushes every edge out by
the margin, which contains the Minkowski sum with a disc of that radius.
"""

from __future__ import annotations

import hashlib
import math
import tomllib
from dataclasses import dataclass, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

__all__ = [
    "Hull",
    "InputAxis",
    "Obstacle",
    "Polygon",
    "Rect",
    "Scenario",
    "ScenarioError",
    "Shape",
    "Target",
    "TrackingMargin",
    "convex_distance_m",
    "hull_footprint",
    "load_scenario",
    "packaged_scenarios",
    "parse_scenario",
]

_EPS = 1e-9


class ScenarioError(ValueError):
    """A scenario that cannot be used; the message names the key and the problem."""


# --------------------------------------------------------------------------- shapes


@dataclass(frozen=True, slots=True)
class Rect:
    """An axis-aligned closed rectangle [x_min, x_max] x [y_min, y_max] (m)."""

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


# --------------------------------------------------------------------------- scenario parts


@dataclass(frozen=True, slots=True)
class InputAxis:
    """One axis of the input grid: values min, min + step, ..., max."""

    min: float
    max: float
    step: float

    def values(self) -> FloatArray:
        """Return the grid values, shape (n,)."""
        n = round((self.max - self.min) / self.step) + 1
        return self.min + self.step * np.arange(n, dtype=np.float64)


@dataclass(frozen=True, slots=True)
class TrackingMargin:
    """Bound on |nu - nu_ref| per axis that the low-level loop guarantees.

    Attributes:
        surge_mps: Surge bound (m/s).
        sway_mps: Sway bound (m/s).
        yaw_rate_radps: Yaw-rate bound (rad/s).
        source: Where the numbers come from.
    """

    surge_mps: float = 0.0
    sway_mps: float = 0.0
    yaw_rate_radps: float = 0.0
    source: str = ""

    def as_array(self) -> FloatArray:
        """Return (surge, sway, yaw rate) as shape (3,)."""
        return np.array([self.surge_mps, self.sway_mps, self.yaw_rate_radps])


@dataclass(frozen=True, slots=True)
class Hull:
    """The vessel's footprint: a rectangle around the body origin (m)."""

    length_m: float = 0.99
    beam_m: float = 0.31


@dataclass(frozen=True, slots=True)
class Obstacle:
    """A real obstacle and the inflation the abstraction uses for it (m)."""

    name: str
    shape: Shape
    inflation_m: float

    @property
    def inflated(self) -> Shape:
        """Return the obstacle grown by its inflation (the abstract obstacle)."""
        return self.shape.inflate(self.inflation_m)

    def translate(self, dx_m: float, dy_m: float) -> Obstacle:
        """Return the obstacle moved by (dx, dy) (m)."""
        return replace(self, shape=self.shape.translate(dx_m, dy_m))


@dataclass(frozen=True, slots=True)
class Target:
    """The real target and the deflation the abstraction uses for it (m)."""

    shape: Shape
    deflation_m: float

    @property
    def deflated(self) -> Shape:
        """Return the target shrunk by its deflation (the abstract target)."""
        return self.shape.inflate(-self.deflation_m)


def hull_footprint(hull: Hull, x_m: float, y_m: float, psi_rad: float) -> Polygon:
    """Return the hull rectangle at pose (x, y, psi) in the arena frame."""
    return Polygon.rotated_rect((x_m, y_m), (hull.length_m, hull.beam_m), psi_rad)


@dataclass(frozen=True, slots=True)
class Scenario:
    """One docking problem: arena, grid, inputs, timing, margin, hull and sets.

    Attributes:
        name: Short name.
        description: One line for people.
        x_range_m: State bounds in x (m).
        y_range_m: State bounds in y (m); heading is always [-pi, pi).
        cell_m: Cell widths in x and y (m).
        heading_cells: Number of heading cells dividing 2 pi.
        surge: Surge input grid (m/s).
        sway: Sway input grid (m/s).
        yaw_rate: Yaw-rate input grid (rad/s).
        tau_s: Sampling time of the abstraction (s).
        margin: Tracking-error margin per axis.
        hull: Hull footprint.
        obstacles: Real obstacles with their inflation.
        target: Real target with its deflation.
    """

    name: str
    description: str
    x_range_m: tuple[float, float]
    y_range_m: tuple[float, float]
    cell_m: tuple[float, float]
    heading_cells: int
    surge: InputAxis
    sway: InputAxis
    yaw_rate: InputAxis
    tau_s: float
    margin: TrackingMargin
    hull: Hull
    obstacles: tuple[Obstacle, ...]
    target: Target

    def digest(self) -> str:
        """Return a short hash of everything in the scenario (for logs and caches)."""
        return hashlib.sha256(repr(self).encode()).hexdigest()[:16]

    @property
    def arena(self) -> Rect:
        """Return the state bounds in (x, y) as a rectangle."""
        return Rect(*self.x_range_m, *self.y_range_m)

    def inputs(self) -> FloatArray:
        """Return every input (surge, sway, yaw rate), shape (m, 3), surge slowest."""
        grids = np.meshgrid(
            self.surge.values(), self.sway.values(), self.yaw_rate.values(), indexing="ij"
        )
        return np.stack([g.ravel() for g in grids], axis=1)

    def inflated_obstacles(self) -> tuple[Shape, ...]:
        """Return the abstract obstacles (inflated)."""
        return tuple(o.inflated for o in self.obstacles)

    def abstract_target(self) -> Shape:
        """Return the abstract target (deflated)."""
        return self.target.deflated

    def with_obstacles(self, obstacles: tuple[Obstacle, ...]) -> Scenario:
        """Return the same scenario with another obstacle layout (validated)."""
        out = replace(self, obstacles=tuple(obstacles))
        _check_sets(out)
        return out

    def with_obstacles_moved(self, offsets_m: FloatArray) -> Scenario:
        """Return the scenario with obstacle n moved by offsets_m[n] ((n_obstacles, 2), m)."""
        offsets = np.asarray(offsets_m, dtype=np.float64).reshape(len(self.obstacles), 2)
        return self.with_obstacles(
            tuple(
                o.translate(float(d[0]), float(d[1]))
                for o, d in zip(self.obstacles, offsets, strict=True)
            )
        )

    def with_margin(self, margin: TrackingMargin) -> Scenario:
        """Return the same scenario with another tracking-error margin."""
        return replace(self, margin=margin)

    def hull_clearance_m(self, x_m: float, y_m: float, psi_rad: float) -> float:
        """Return the distance from the hull at (x, y, psi) to the nearest real obstacle (m).

        Returns 0 when the hull touches or overlaps an obstacle and inf with none.
        """
        hull = hull_footprint(self.hull, x_m, y_m, psi_rad)
        return min((convex_distance_m(hull, o.shape) for o in self.obstacles), default=math.inf)

    def wall_clearance_m(self, x_m: float, y_m: float, psi_rad: float) -> float:
        """Return the distance from the hull at (x, y, psi) to the arena walls (m, <0 outside)."""
        v = hull_footprint(self.hull, x_m, y_m, psi_rad).vertices()
        return float(
            min(
                v[:, 0].min() - self.x_range_m[0],
                self.x_range_m[1] - v[:, 0].max(),
                v[:, 1].min() - self.y_range_m[0],
                self.y_range_m[1] - v[:, 1].max(),
            )
        )


# --------------------------------------------------------------------------- parsing

_TOP_KEYS = {
    "name",
    "description",
    "state",
    "grid",
    "inputs",
    "timing",
    "margin",
    "hull",
    "abstraction",
    "obstacles",
    "target",
}


def _table(data: dict[str, Any], key: str, where: str) -> dict[str, Any]:
    if key not in data:
        raise ScenarioError(f"missing key {where}{key!r}")
    value = data[key]
    if not isinstance(value, dict):
        raise ScenarioError(f"key {where}{key!r} must be a table, got {value!r}")
    return value


def _check_keys(data: dict[str, Any], allowed: set[str], where: str) -> None:
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise ScenarioError(
            f"unknown key {where}{unknown[0]!r} (allowed: {', '.join(sorted(allowed))}); "
            "keys carry their unit (_m, _s, _mps, _radps, _rad)"
        )


def _number(data: dict[str, Any], key: str, where: str, default: float | None = None) -> float:
    if key not in data:
        if default is None:
            raise ScenarioError(f"missing key {where}{key!r}")
        return default
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ScenarioError(f"key {where}{key!r} must be a finite number, got {value!r}")
    return float(value)


def _numbers(data: dict[str, Any], key: str, where: str, n: int) -> tuple[float, ...]:
    if key not in data:
        raise ScenarioError(f"missing key {where}{key!r}")
    value = data[key]
    if (
        not isinstance(value, list)
        or len(value) != n
        or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
        or not all(math.isfinite(v) for v in value)
    ):
        raise ScenarioError(
            f"key {where}{key!r} must be a list of {n} finite numbers, got {value!r}"
        )
    return tuple(float(v) for v in value)


def _interval(data: dict[str, Any], key: str, where: str) -> tuple[float, float]:
    lo, hi = _numbers(data, key, where, 2)
    if not hi > lo:
        raise ScenarioError(f"key {where}{key!r} is empty: {[lo, hi]!r} needs min < max")
    return lo, hi


def _divides(length: float, step: float) -> bool:
    n = length / step
    return abs(n - round(n)) < 1e-6 and round(n) >= 1


def _shape(data: dict[str, Any], where: str) -> Shape:
    if "center_m" in data:
        _check_keys(
            data, {"name", "center_m", "size_m", "angle_rad", "inflation_m", "deflation_m"}, where
        )
        cx, cy = _numbers(data, "center_m", where, 2)
        length, width = _numbers(data, "size_m", where, 2)
        if not (length > 0.0 and width > 0.0):
            raise ScenarioError(f"key {where}'size_m' is empty: {[length, width]!r}")
        return Polygon.rotated_rect(
            (cx, cy), (length, width), _number(data, "angle_rad", where, 0.0)
        )
    if "vertices_m" in data:
        _check_keys(data, {"name", "vertices_m", "inflation_m", "deflation_m"}, where)
        raw = data["vertices_m"]
        if not isinstance(raw, list) or not all(
            isinstance(p, list) and len(p) == 2 and all(isinstance(c, int | float) for c in p)
            for p in raw
        ):
            raise ScenarioError(
                f"key {where}'vertices_m' must be a list of [x, y] pairs, got {raw!r}"
            )
        poly = Polygon(tuple((float(p[0]), float(p[1])) for p in raw))
        if poly.is_empty():
            raise ScenarioError(
                f"key {where}'vertices_m' is not a convex counter-clockwise polygon "
                f"with area: {raw!r}"
            )
        return poly
    _check_keys(data, {"name", "x_m", "y_m", "inflation_m", "deflation_m"}, where)
    x = _interval(data, "x_m", where)
    y = _interval(data, "y_m", where)
    return Rect(x[0], x[1], y[0], y[1])


def _axis(data: dict[str, Any], key: str, where: str) -> InputAxis:
    lo, hi, step = _numbers(data, key, where, 3)
    if not ((step > 0.0 and hi >= lo and _divides(hi - lo, step)) or hi == lo):
        raise ScenarioError(
            f"key {where}{key!r} = {[lo, hi, step]!r}: need [min, max, step] "
            "with step > 0 dividing max - min"
        )
    return InputAxis(lo, hi, step)


def parse_scenario(data: dict[str, Any], default_name: str = "scenario") -> Scenario:
    """Build a scenario from parsed TOML data, validating every key.

    Raises:
        ScenarioError: A key is missing, unknown, of the wrong type or inconsistent.
    """
    _check_keys(data, _TOP_KEYS, "")
    state = _table(data, "state", "")
    _check_keys(state, {"x_m", "y_m"}, "state.")
    x_range = _interval(state, "x_m", "state.")
    y_range = _interval(state, "y_m", "state.")

    grid = _table(data, "grid", "")
    _check_keys(grid, {"cell_m", "heading_cells", "heading_cell_rad"}, "grid.")
    cell = _numbers(grid, "cell_m", "grid.", 2)
    if not (cell[0] > 0.0 and cell[1] > 0.0):
        raise ScenarioError(f"key grid.'cell_m' must be positive, got {list(cell)!r}")
    if not _divides(x_range[1] - x_range[0], cell[0]):
        raise ScenarioError(
            f"key grid.'cell_m' x width {cell[0]!r} does not divide state.x_m {list(x_range)!r}"
        )
    if not _divides(y_range[1] - y_range[0], cell[1]):
        raise ScenarioError(
            f"key grid.'cell_m' y width {cell[1]!r} does not divide state.y_m {list(y_range)!r}"
        )
    if "heading_cells" in grid:
        heading_cells = grid["heading_cells"]
        if (
            isinstance(heading_cells, bool)
            or not isinstance(heading_cells, int)
            or heading_cells < 1
        ):
            raise ScenarioError(
                f"key grid.'heading_cells' must be a positive integer, got {heading_cells!r}"
            )
    else:
        width = _number(grid, "heading_cell_rad", "grid.")
        if not (width > 0.0 and _divides(2.0 * math.pi, width)):
            raise ScenarioError(f"key grid.'heading_cell_rad' = {width!r} does not divide 2 pi")
        heading_cells = round(2.0 * math.pi / width)

    inputs = _table(data, "inputs", "")
    _check_keys(inputs, {"surge_mps", "sway_mps", "yaw_rate_radps"}, "inputs.")
    surge = _axis(inputs, "surge_mps", "inputs.")
    sway = _axis(inputs, "sway_mps", "inputs.")
    yaw = _axis(inputs, "yaw_rate_radps", "inputs.")
    if max(abs(yaw.min), abs(yaw.max)) > math.pi:
        raise ScenarioError(
            f"key inputs.'yaw_rate_radps' = {[yaw.min, yaw.max]!r} exceeds pi rad/s: degrees given?"
        )

    timing = _table(data, "timing", "")
    _check_keys(timing, {"tau_s"}, "timing.")
    tau = _number(timing, "tau_s", "timing.")
    if not 0.0 < tau <= 60.0:
        raise ScenarioError(
            f"key timing.'tau_s' = {tau!r} must be in (0, 60] s (milliseconds given?)"
        )

    margin_data = data.get("margin", {})
    if not isinstance(margin_data, dict):
        raise ScenarioError(f"key 'margin' must be a table, got {margin_data!r}")
    _check_keys(margin_data, {"surge_mps", "sway_mps", "yaw_rate_radps", "source"}, "margin.")
    margin = TrackingMargin(
        _number(margin_data, "surge_mps", "margin.", 0.0),
        _number(margin_data, "sway_mps", "margin.", 0.0),
        _number(margin_data, "yaw_rate_radps", "margin.", 0.0),
        str(margin_data.get("source", "")),
    )
    for key, value in (
        ("surge_mps", margin.surge_mps),
        ("sway_mps", margin.sway_mps),
        ("yaw_rate_radps", margin.yaw_rate_radps),
    ):
        if value < 0.0:
            raise ScenarioError(f"key margin.{key!r} must be >= 0, got {value!r}")

    hull_data = data.get("hull", {})
    if not isinstance(hull_data, dict):
        raise ScenarioError(f"key 'hull' must be a table, got {hull_data!r}")
    _check_keys(hull_data, {"length_m", "beam_m"}, "hull.")
    hull = Hull(
        _number(hull_data, "length_m", "hull.", 0.99), _number(hull_data, "beam_m", "hull.", 0.31)
    )
    if not (hull.length_m > 0.0 and hull.beam_m > 0.0):
        raise ScenarioError(f"key 'hull' must have positive sizes, got {hull!r}")

    abstraction = data.get("abstraction", {})
    if not isinstance(abstraction, dict):
        raise ScenarioError(f"key 'abstraction' must be a table, got {abstraction!r}")
    _check_keys(abstraction, {"obstacle_inflation_m", "target_deflation_m"}, "abstraction.")
    inflation = _number(abstraction, "obstacle_inflation_m", "abstraction.", 0.0)
    deflation = _number(abstraction, "target_deflation_m", "abstraction.", 0.0)
    if inflation < 0.0 or deflation < 0.0:
        raise ScenarioError(f"keys abstraction.* must be >= 0, got {abstraction!r}")

    raw_obstacles = data.get("obstacles", [])
    if not isinstance(raw_obstacles, list):
        raise ScenarioError(f"key 'obstacles' must be an array of tables, got {raw_obstacles!r}")
    obstacles = []
    for n, raw in enumerate(raw_obstacles):
        where = f"obstacles[{n}]."
        if not isinstance(raw, dict):
            raise ScenarioError(f"key {where[:-1]!r} must be a table, got {raw!r}")
        obstacles.append(
            Obstacle(
                str(raw.get("name", f"O{n + 1}")),
                _shape(raw, where),
                _number(raw, "inflation_m", where, inflation),
            )
        )
    target_data = _table(data, "target", "")
    target = Target(
        _shape(target_data, "target."), _number(target_data, "deflation_m", "target.", deflation)
    )

    scenario = Scenario(
        name=str(data.get("name", default_name)),
        description=str(data.get("description", "")),
        x_range_m=x_range,
        y_range_m=y_range,
        cell_m=(cell[0], cell[1]),
        heading_cells=int(heading_cells),
        surge=surge,
        sway=sway,
        yaw_rate=yaw,
        tau_s=tau,
        margin=margin,
        hull=hull,
        obstacles=tuple(obstacles),
        target=target,
    )
    _check_sets(scenario)
    return scenario


def _check_sets(scenario: Scenario) -> None:
    target = scenario.abstract_target()
    if target.is_empty():
        raise ScenarioError(
            f"key 'target' is empty after deflation by {scenario.target.deflation_m!r} m: "
            f"{target!r}"
        )
    if not shapes_overlap(target, scenario.arena):
        raise ScenarioError(
            f"key 'target' {target!r} lies outside the state bounds {scenario.arena!r}"
        )
    for n, obstacle in enumerate(scenario.obstacles):
        if obstacle.shape.is_empty() or obstacle.inflation_m < 0.0:
            raise ScenarioError(
                f"key obstacles[{n}] ({obstacle.name!r}) is empty: {obstacle.shape!r}"
            )
        if shapes_overlap(obstacle.shape, scenario.target.shape):
            raise ScenarioError(
                f"key 'target' {scenario.target.shape!r} overlaps "
                f"obstacles[{n}] ({obstacle.name!r})"
            )


def packaged_scenarios() -> list[str]:
    """Return the names of the scenarios shipped with the package."""
    folder = resources.files("hil") / "scenarios"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load a packaged scenario by name ("paper", "coarse") or any TOML file by path.

    Raises:
        ScenarioError: The file is missing, is not TOML, or fails validation.
    """
    text: str
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as err:
            raise ScenarioError(f"cannot read scenario file {str(path)!r}: {err}") from err
        default = path.stem
    else:
        name = str(name_or_path)
        resource = resources.files("hil") / "scenarios" / f"{name}.toml"
        if not resource.is_file():
            raise ScenarioError(
                f"no scenario named {name!r} (packaged: {', '.join(packaged_scenarios())}; "
                "or give a path to a .toml file)"
            )
        text = resource.read_text(encoding="utf-8")
        default = name
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ScenarioError(f"scenario {str(name_or_path)!r} is not valid TOML: {err}") from err
    return parse_scenario(data, default)
