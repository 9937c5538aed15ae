"""Docking scenarios: the arena, the grid, the inputs and the sets of one problem.

A scenario is a frozen description of one reach-avoid problem in the arena frame
(x, y in metres, heading psi in radians wrapped to [-pi, pi)). It keeps both the
real obstacles (for hull clearance at run time) and the abstract sets the
controller is synthesized for (obstacles inflated, target deflated; PAPER.md,
Fig. 3). Shapes come from :mod:`hil.core.shapes`; reading a scenario from TOML is
:mod:`hil.scenarios.parse`, finding one by name :mod:`hil.scenarios.catalog`.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field, replace

import numpy as np

from hil.core.arrays import FloatArray
from hil.core.motion import ObstacleMotion
from hil.core.pose_feeds import DEFAULT_POSE_FEED
from hil.core.shapes import Polygon, Rect, Shape, convex_distance_m, shapes_overlap
from hil.core.transient import LATE_S, TransientBudget, horizon_bins
from hil.scenarios.errors import ScenarioError

__all__ = [
    "Hull",
    "InputAxis",
    "Obstacle",
    "ObstacleTracking",
    "Scenario",
    "SimulatedWorld",
    "Target",
    "check_geometry",
    "check_sets",
    "check_transient",
    "hull_footprint",
]



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
class Hull:
    """The vessel's footprint: a rectangle around the body origin (m)."""

    length_m: float = 0.99
    beam_m: float = 0.31


@dataclass(frozen=True, slots=True)
class Obstacle:
    """A real obstacle, the inflation the abstraction uses for it and its speed bound.

    Attributes:
        name: Short name.
        shape: Where it was last reported (arena frame, m).
        inflation_m: The centre keeps this far from it (m): the abstract obstacle.
        max_speed_mps: Bound on its speed (m/s); 0 for a fixed obstacle.
    """

    name: str
    shape: Shape
    inflation_m: float
    max_speed_mps: float = 0.0

    @property
    def inflated(self) -> Shape:
        """Return the obstacle grown by its inflation (the abstract obstacle)."""
        return self.shape.inflate(self.inflation_m)

    def reach(self, horizon_s: float, lag_m: float = 0.0) -> Shape:
        """Return where the obstacle may be within `horizon_s` of its report (s).

        The shape grown by ``max_speed_mps * horizon_s + lag_m`` on every side (lag_m:
        how far the report may trail the tracker, m), which contains the shape swept
        along any path of that length; the shape itself for a fixed obstacle.
        """
        if self.max_speed_mps <= 0.0:
            return self.shape
        return self.shape.inflate(self.max_speed_mps * horizon_s + lag_m)

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


REPORT_AGES = ("stated", "measured")
"""``[obstacle_motion] report_age``: the scenario's age, or the runtime's measurement."""


@dataclass(frozen=True, slots=True)
class ObstacleTracking:
    """What a decision may assume about obstacles that move (the ``[obstacle_motion]`` table).

    An obstacle with ``max_speed_mps`` > 0 is tracked: a controller synthesized from its
    report at ``t_r`` is used for decisions only while the report is at most
    ``max_report_age_s`` old, and each decision's interval lasts at most tau +
    :data:`~hil.core.transient.LATE_S`, so the synthesis avoids where it may be up to
    :meth:`horizon_s` after ``t_r`` (:meth:`Obstacle.reach`). A report older than that
    stops the vessel until a fresher one (the runtime's ``obstacles_stale`` event).

    Attributes:
        max_report_age_s: Oldest a tracked obstacle's report may be at a decision (s):
            the age every controller is solved for, or with ``report_age`` "measured"
            the one until the runtime measured its own (:mod:`hil.runtime.report_age`).
        position_tolerance_m: How far a tracked obstacle's reported position may lag the
            tracker's latest (m): the ROS tracker keeps a layout until some centre moved
            this far, so a small move does not cost a re-synthesis; moving obstacles are
            grown by it too.
        report_age: "stated" (``max_report_age_s`` for every controller) or "measured"
            (each controller's age from the ages the runtime measured).
    """

    max_report_age_s: float = 1.0
    position_tolerance_m: float = 0.01
    report_age: str = "stated"

    def __repr__(self) -> str:
        # The scenario's digest is its repr: "stated" (the default, and all there was
        # before "measured") leaves it out, so older scenarios keep the hash their logs carry.
        extra = "" if self.report_age == "stated" else f", report_age={self.report_age!r}"
        return (
            f"ObstacleTracking(max_report_age_s={self.max_report_age_s!r}, "
            f"position_tolerance_m={self.position_tolerance_m!r}{extra})"
        )

    @property
    def measures_report_age(self) -> bool:
        """Whether each controller's report age comes from the runtime's measurement."""
        return self.report_age == "measured"

    def horizon_s(self, tau_s: float) -> float:
        """Return how long after its report a tracked obstacle is avoided (s)."""
        return self.max_report_age_s + tau_s + LATE_S


@dataclass(frozen=True, slots=True)
class SimulatedWorld:
    """What the simulated world does with the obstacles (``[[simulated_motion]]``, ``[sim]``).

    Not part of the problem the controller solves: the stack sees only the obstacle
    reports, and the speed bounds it is synthesized for are the obstacles'
    ``max_speed_mps``, which every motion here respects (:mod:`hil.scenarios.parse`
    refuses a faster one).

    Attributes:
        motions: Scheduled constant-velocity motions; ``index`` is the position of the
            obstacle in :attr:`Scenario.obstacles`. Motions of one obstacle do not overlap
            in time, so its speed never exceeds its bound.
        obstacle_report_period_s: How often the simulated tracker reports every obstacle
            when some motion is scheduled (s).
    """

    motions: tuple[ObstacleMotion, ...] = ()
    obstacle_report_period_s: float = 1.0

    @property
    def moves_obstacles(self) -> bool:
        """Whether some obstacle moves in simulation (a motion with a velocity and a span)."""
        return any(m.stop_s > m.start_s and any(m.velocity_mps) for m in self.motions)


def hull_footprint(hull: Hull, x_m: float, y_m: float, psi_rad: float) -> Polygon:
    """Return the hull rectangle at pose (x, y, psi) in the arena frame."""
    return Polygon.rotated_rect((x_m, y_m), (hull.length_m, hull.beam_m), psi_rad)


@dataclass(frozen=True, slots=True)
class Scenario:
    """One docking problem: arena, grid, inputs, timing, budget, hull and sets.

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
        transient: Time-resolved bounds on the deviation from the exact arc (and the
            velocity error) per period class, and the EKF's pose error
            (:class:`~hil.core.transient.TransientBudget`); its bins cover `tau_s` +
            :data:`~hil.core.transient.LATE_S`.
        hull: Hull footprint.
        obstacles: Real obstacles with their inflation and speed bound.
        target: Real target with its deflation.
        tracking: The report age a decision may rely on for obstacles that move.
        simulation: What the obstacles do in simulation (``[[simulated_motion]]``,
            ``[sim]``); left out of ``repr`` so that a scenario without it keeps its
            digest, and added to :meth:`digest` when set.
        pose_feeds: The budget measured for each other pose feed
            (``[pose_feeds.NAME]``, :mod:`hil.core.pose_feeds`), by name; `transient`
            is the one for :data:`~hil.core.pose_feeds.DEFAULT_POSE_FEED`. Left out of
            ``repr``: the digest is of the budget in force (:meth:`for_pose_feed`).
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
    transient: TransientBudget
    hull: Hull
    obstacles: tuple[Obstacle, ...]
    target: Target
    tracking: ObstacleTracking = ObstacleTracking()
    simulation: SimulatedWorld = field(default=SimulatedWorld(), repr=False)
    pose_feeds: tuple[tuple[str, TransientBudget], ...] = field(default=(), repr=False)

    def for_pose_feed(self, name: str) -> Scenario:
        """Return this scenario with the budget measured for pose feed `name` in force.

        Raises:
            ScenarioError: The scenario ships no budget for that feed (the message names
                the table to add and the command that measures it).
        """
        if name == DEFAULT_POSE_FEED:
            return self
        budget = dict(self.pose_feeds).get(name)
        if budget is None:
            shipped = ", ".join([DEFAULT_POSE_FEED, *(n for n, _ in self.pose_feeds)])
            raise ScenarioError(
                f"scenario {self.name!r} has no premises for pose feed {name!r} (it has: "
                f"{shipped}): add a [pose_feeds.{name}] table (measure it with `python -m "
                f"bench lowlevel --transient-only --pose-feed {name}`) or set pose_feed to "
                "one it has")
        return replace(self, transient=budget)

    def digest(self) -> str:
        """Return a short hash of everything in the scenario (for logs and caches).

        The transient budget's numbers enter by their own digest (its ``repr``); the
        simulated world enters only when it is not the default (no motion, reports every
        second), so scenarios written before it existed keep the hash their logs carry.
        """
        text = repr(self)
        if self.simulation != SimulatedWorld():
            text += repr(self.simulation)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

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

    @property
    def tracks_obstacles(self) -> bool:
        """Whether some obstacle may move (a speed bound above zero)."""
        return any(o.max_speed_mps > 0.0 for o in self.obstacles)

    def obstacle_reach(self) -> tuple[Shape, ...]:
        """Return the real obstacles grown by their motion over the tracking horizon.

        What a controller synthesized from the obstacles' reports must avoid
        (:meth:`Obstacle.reach` over :meth:`ObstacleTracking.horizon_s`); the real
        obstacles themselves when none moves.
        """
        horizon = self.tracking.horizon_s(self.tau_s)
        lag = self.tracking.position_tolerance_m
        return tuple(o.reach(horizon, lag) for o in self.obstacles)

    def inflated_obstacles(self) -> tuple[Shape, ...]:
        """Return the abstract obstacles (inflated)."""
        return tuple(o.inflated for o in self.obstacles)

    def abstract_target(self) -> Shape:
        """Return the abstract target (deflated)."""
        return self.target.deflated

    def with_obstacles(self, obstacles: tuple[Obstacle, ...]) -> Scenario:
        """Return the same scenario with another obstacle layout (validated)."""
        out = replace(self, obstacles=tuple(obstacles))
        check_sets(out)
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

    def with_report_age(self, report_age_s: float) -> Scenario:
        """Return the scenario whose tracked obstacles are avoided for reports `report_age_s` old.

        Raises:
            ScenarioError: An age that is not > 0.
        """
        if not report_age_s > 0.0:
            raise ScenarioError(f"a report age must be > 0 s, got {report_age_s!r}")
        if report_age_s == self.tracking.max_report_age_s:
            return self
        return replace(self, tracking=replace(self.tracking, max_report_age_s=report_age_s))

    def with_transient(self, budget: TransientBudget) -> Scenario:
        """Return the same scenario with another transient budget.

        Raises:
            ScenarioError: The budget's bins do not cover a period held late (`tau_s` +
                :data:`~hil.core.transient.LATE_S`).
        """
        check_transient(budget, self.tau_s)
        return replace(self, transient=budget)

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


def check_transient(budget: TransientBudget, tau_s: float) -> None:
    """Check that a transient budget's bins cover a command period held late, and no more.

    A period lasts ``tau_s`` to ``tau_s + LATE_S`` (a command held up to two 20-Hz ticks
    late): the budget must have the fewest bins of its ``bin_s`` that cover that.

    Raises:
        ScenarioError: The budget has another number of bins.
    """
    need = horizon_bins(tau_s, budget.bin_s)
    if budget.n_bins != need:
        raise ScenarioError(
            f"key transient.'bin_s' = {budget.bin_s!r} with {budget.n_bins} bins covers "
            f"{budget.horizon_s()!r} s, not a period held late, timing.'tau_s' + {LATE_S!r} = "
            f"{tau_s + LATE_S!r} s (need {need} bins)"
        )


def check_sets(scenario: Scenario) -> None:
    """Check that the scenario's sets fit together: target usable, no obstacle on it.

    Raises:
        ScenarioError: The deflated target is empty or outside the arena, an obstacle
            is empty, or an obstacle overlaps the real target.
    """
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


def check_geometry(scenario: Scenario) -> None:
    """Check a scenario file's layout: obstacles inside the arena, the target reachable.

    Only for the scenario as written: obstacles reported at run time may leave the
    arena, and whether their layout has a solution is the synthesis' answer.

    Raises:
        ScenarioError: An obstacle reaches outside the arena, or every point of the
            abstract target is covered by the walls or the inflated obstacles.
    """
    x0, x1 = scenario.x_range_m
    y0, y1 = scenario.y_range_m
    tol = 1e-9
    for n, obstacle in enumerate(scenario.obstacles):
        v = obstacle.shape.vertices()
        if (v[:, 0].min() < x0 - tol or v[:, 0].max() > x1 + tol
                or v[:, 1].min() < y0 - tol or v[:, 1].max() > y1 + tol):
            raise ScenarioError(
                f"key obstacles[{n}] ({obstacle.name!r}) {obstacle.shape!r} reaches outside "
                f"the arena state.x_m {list(scenario.x_range_m)!r}, "
                f"state.y_m {list(scenario.y_range_m)!r}"
            )
    target = scenario.abstract_target()
    if not _has_free_point(scenario, target):
        raise ScenarioError(
            f"key 'target' cannot be reached: its abstract set {target!r} lies inside the "
            "arena walls or the inflated obstacles (abstraction.obstacle_inflation_m)"
        )


def _point(x_m: float, y_m: float) -> Rect:
    return Rect(x_m, x_m, y_m, y_m)


def _has_free_point(scenario: Scenario, target: Shape, samples: int = 9) -> bool:
    """Whether some point of `target`, on a samples x samples lattice, is free and in the arena.

    A necessary condition for reaching the target: a point covered by an inflated
    obstacle is unsafe for the abstraction, so a target entirely covered has no
    winning cell. (Whether a start can reach it is the synthesis' answer.)
    """
    v = target.vertices()
    inflated = scenario.inflated_obstacles()
    for x in np.linspace(v[:, 0].min(), v[:, 0].max(), samples):
        for y in np.linspace(v[:, 1].min(), v[:, 1].max(), samples):
            p = _point(float(x), float(y))
            inside = (scenario.x_range_m[0] < x < scenario.x_range_m[1]
                      and scenario.y_range_m[0] < y < scenario.y_range_m[1])
            if (inside and convex_distance_m(p, target) == 0.0
                    and all(convex_distance_m(p, o) > 0.0 for o in inflated)):
                return True
    return False


def check_start(scenario: Scenario, x_m: float, y_m: float, psi_rad: float) -> None:
    """Check that a start pose is physically possible: in the arena, clear of every obstacle.

    Whether the controller can dock from there (the winning set) is the synthesis'
    answer; this only refuses what no controller could fix.

    Raises:
        ScenarioError: The pose is not finite, the body origin lies outside the arena,
            a hull corner lies past a wall, or the hull overlaps a real obstacle.
    """
    pose = (x_m, y_m, psi_rad)
    if not all(math.isfinite(v) for v in pose):
        raise ScenarioError(f"start {pose!r} is not finite")
    x0, x1 = scenario.x_range_m
    y0, y1 = scenario.y_range_m
    if not (x0 <= x_m <= x1 and y0 <= y_m <= y1):
        raise ScenarioError(
            f"start ({x_m!r}, {y_m!r}) is outside the arena x {[x0, x1]!r} m, y {[y0, y1]!r} m"
        )
    hull = hull_footprint(scenario.hull, x_m, y_m, psi_rad)
    corners = hull.vertices()
    outside = (
        (corners[:, 0] < x0) | (corners[:, 0] > x1) | (corners[:, 1] < y0) | (corners[:, 1] > y1)
    )
    if outside.any():
        cx, cy = (float(v) for v in corners[np.argmax(outside)])
        raise ScenarioError(
            f"start ({x_m!r}, {y_m!r}, {math.degrees(psi_rad):.1f} deg) puts a hull corner "
            f"past the arena's wall, at ({cx:.3f}, {cy:.3f}) m (arena x {[x0, x1]!r} m, "
            f"y {[y0, y1]!r} m)"
        )
    for obstacle in scenario.obstacles:
        if convex_distance_m(hull, obstacle.shape) == 0.0:
            where = "inside" if convex_distance_m(_point(x_m, y_m), obstacle.shape) == 0.0 \
                else "touching"
            raise ScenarioError(
                f"start ({x_m!r}, {y_m!r}, {math.degrees(psi_rad):.1f} deg) puts the hull "
                f"{where} obstacle {obstacle.name!r} {obstacle.shape!r}"
            )
