"""The guarantee judged on the true state: what each decision assumed against what happened.

For a simulated run, every decision that chose an input is held to its
:class:`~hil.controllers.symbolic.DecisionContract` on the simulator's true
trajectory (100 Hz): the centre in the tube's cells over [t, t + tau], the state
in the successor cells at t + tau, the value there strictly smaller. Besides the
contract, every span between decisions is judged for safety against the real world:
the centre inside an inflated obstacle (the abstract obstacle), the hull touching a
real obstacle, the hull outside the arena; and for the premises the abstraction
does not model: an interval held longer than tau (late tick or pose-loss hold) and
a true start cell other than the decision's (estimation error). Obstacles are
judged where they truly are at each step (scheduled motions applied).

Counts are of intervals (spans), not samples; each comes with the size of its
worst violation: metres for positions and penetrations, radians for headings,
seconds for lateness.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, fields
from itertools import pairwise

import numpy as np

from hil.controllers.symbolic import Controller, DecisionContract, Select, cells_of
from hil.core.arrays import FloatArray
from hil.core.clock import NS_PER_S
from hil.core.motion import ObstacleMotion, displacements_m
from hil.core.records import Decision
from hil.core.shapes import Shape
from hil.runs.clearance import hull_corners
from hil.runs.sim_run import SimOutcome, SimRunSpec, simulate
from hil.runs.summary import RunSummary
from hil.runtime.trace import MemoryLog
from hil.scenarios import Scenario
from hil.sim.plant import TR_ETA

__all__ = ["GuaranteeViolations", "judge_outcome", "judge_run", "judged_run"]



@dataclass(frozen=True, slots=True)
class GuaranteeViolations:
    """Guarantee violations of one run (or a campaign) on the true state.

    Attributes:
        decisions: Decisions taken.
        intervals: Decisions with a chosen input, judged against their contract.
        tube_exits: Intervals whose centre left the tube cells within tau.
        successor_misses: Intervals whose state at tau was not in the successor cells
            (position or heading).
        value_not_decreasing: Intervals whose value at tau was not strictly smaller.
        inflated_obstacle: Spans with the centre inside an inflated (abstract) obstacle.
        hull_contacts: Spans with the hull touching a real obstacle.
        hull_outside_arena: Spans with a hull corner outside the arena.
        late_intervals: Intervals held longer than the tables cover (tau + late_s) plus
            half a loop period.
        estimation_misses: Decisions whose true start lay farther from the decision's
            cell than the budget's estimation bound.
        worst_tube_exit_m: Largest distance of the centre to the tube cells (m).
        worst_successor_miss_m: Largest distance at tau to the successor cells (m).
        worst_heading_miss_rad: Largest angle at tau to the successor headings (rad).
        worst_inflated_depth_m: Deepest the centre went into an inflated obstacle (m).
        worst_hull_penetration_m: Deepest the hull overlapped a real obstacle (m).
        worst_hull_outside_m: Farthest a hull corner went outside the arena (m).
        worst_late_s: Longest an interval overran tau (s).
        worst_estimation_m: Largest distance of the true start to the decision's cell (m).
    """

    decisions: int = 0
    intervals: int = 0
    tube_exits: int = 0
    successor_misses: int = 0
    value_not_decreasing: int = 0
    inflated_obstacle: int = 0
    hull_contacts: int = 0
    hull_outside_arena: int = 0
    late_intervals: int = 0
    estimation_misses: int = 0
    worst_tube_exit_m: float = 0.0
    worst_successor_miss_m: float = 0.0
    worst_heading_miss_rad: float = 0.0
    worst_inflated_depth_m: float = 0.0
    worst_hull_penetration_m: float = 0.0
    worst_hull_outside_m: float = 0.0
    worst_late_s: float = 0.0
    worst_estimation_m: float = 0.0

    @property
    def violations(self) -> int:
        """Return the number of violated promises of the guarantee (counts summed).

        Late intervals and estimation misses are premises, not promises: not included.
        """
        return (self.tube_exits + self.successor_misses + self.value_not_decreasing
                + self.inflated_obstacle + self.hull_contacts + self.hull_outside_arena)

    @staticmethod
    def total(runs: Iterable[GuaranteeViolations]) -> GuaranteeViolations:
        """Return the counts summed and the worst sizes maximized over `runs`."""
        out: dict[str, float] = {}
        for run in runs:
            for f in fields(GuaranteeViolations):
                value = getattr(run, f.name)
                if f.name.startswith("worst_"):
                    out[f.name] = max(out.get(f.name, 0.0), float(value))
                else:
                    out[f.name] = out.get(f.name, 0) + int(value)
        return GuaranteeViolations(**out)  # type: ignore[arg-type]


def _halfplanes(shape: Shape) -> tuple[FloatArray, FloatArray]:
    """Return outward unit normals (M, 2) and offsets (M,): shape = {p : N p <= c}."""
    v = shape.vertices()
    edges = np.roll(v, -1, axis=0) - v
    normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return normals, np.sum(normals * v, axis=1)


def _depth_m(points: FloatArray, shape: Shape) -> FloatArray:
    """Signed depth of points (N, 2) in a convex shape: > 0 inside, the distance to its edge."""
    normals, offsets = _halfplanes(shape)
    out: FloatArray = (offsets[None, :] - points @ normals.T).min(axis=1)
    return out


def _penetration_m(hulls: FloatArray, shape: Shape) -> FloatArray:
    """Overlap of hulls (N, 4, 2) with a convex shape along the best separating axis (m).

    Zero where they are apart (separating-axis theorem: the least overlap over the
    edge normals of both is the penetration depth of two convex polygons).
    """
    obstacle = shape.vertices()
    hull_edges = np.roll(hulls, -1, axis=1) - hulls
    hull_axes = np.stack([hull_edges[..., 1], -hull_edges[..., 0]], axis=-1)
    obs_axes, _ = _halfplanes(shape)
    axes = np.concatenate(
        [hull_axes / np.linalg.norm(hull_axes, axis=-1, keepdims=True),
         np.broadcast_to(obs_axes, (len(hulls), *obs_axes.shape))], axis=1)
    ph = np.einsum("nvd,nad->nav", hulls, axes)
    po = np.einsum("md,nad->nam", obstacle, axes)
    overlap = np.minimum(ph.max(axis=2), po.max(axis=2)) - np.maximum(ph.min(axis=2),
                                                                      po.min(axis=2))
    out: FloatArray = np.maximum(overlap.min(axis=1), 0.0)
    return out


@dataclass(frozen=True, slots=True)
class _Safety:
    inflated_depth: FloatArray  # (N,) deepest into an inflated obstacle; < 0 outside
    penetration: FloatArray  # (N,) hull overlap with a real obstacle; 0 apart
    outside: FloatArray  # (N,) farthest hull corner outside the arena; <= 0 inside


def _safety(scenario: Scenario, t_s: FloatArray, eta: FloatArray,
            motions: Sequence[ObstacleMotion]) -> _Safety:
    n = len(eta)
    depth = np.full(n, -np.inf)
    pen = np.zeros(n)
    offsets = displacements_m(motions, len(scenario.obstacles), t_s)
    for index, obstacle in enumerate(scenario.obstacles):
        # Judge in the obstacle's frame: move the vessel back by the obstacle's motion.
        rel = eta.copy()
        rel[:, :2] -= offsets[index]
        depth = np.maximum(depth, _depth_m(rel[:, :2], obstacle.inflated))
        hulls = hull_corners(scenario.hull.length_m, scenario.hull.beam_m, rel)
        pen = np.maximum(pen, _penetration_m(hulls, obstacle.shape))
    hulls = hull_corners(scenario.hull.length_m, scenario.hull.beam_m, eta)
    (x0, x1), (y0, y1) = scenario.x_range_m, scenario.y_range_m
    outside = np.maximum.reduce([
        x0 - hulls[..., 0].min(axis=1), hulls[..., 0].max(axis=1) - x1,
        y0 - hulls[..., 1].min(axis=1), hulls[..., 1].max(axis=1) - y1])
    return _Safety(depth, pen, outside)


def _cell_distance_m(controller: Controller, cell: tuple[int, int, int],
                     pose: FloatArray) -> float:
    lo, hi = controller.grid.cell_bounds(*cell)
    dx = max(lo[0] - pose[0], 0.0, pose[0] - hi[0])
    dy = max(lo[1] - pose[1], 0.0, pose[1] - hi[1])
    return math.hypot(dx, dy)


def judge_run(
    scenario: Scenario,
    decisions: Sequence[Decision],
    controllers: Mapping[int, Controller],
    t_s: FloatArray,
    eta: FloatArray,
    *,
    motions: Sequence[ObstacleMotion] = (),
    tick_s: float = 0.05,
) -> GuaranteeViolations:
    """Judge a run's decisions against its true trajectory.

    Args:
        scenario: The scenario (real obstacles, inflation, hull, arena).
        decisions: The run's decisions, in time order.
        controllers: The controller behind each ``controller_version``; a decision
            whose version is missing is judged for safety only.
        t_s: Times of the true states (s), shape (N,), uniformly spaced, on the clock of
            the decisions' stamps (a simulated run's from 0; a recorded true trajectory's
            from wherever it starts, see :mod:`hil.replay.truth`).
        eta: True poses (x m, y m, psi rad), shape (N, 3) indexed [time, axis].
        motions: Scheduled obstacle motions (the real obstacles' true positions: each
            obstacle displaced by the sum of its motions at each time, as the simulator
            moves it).
        tick_s: Loop period (s): an interval counts as late past tau + tick_s / 2.

    Returns:
        Counts of intervals with each violation and the worst sizes.
    """
    eta = np.asarray(eta, dtype=np.float64).reshape(-1, 3)
    n = len(eta)
    if n == 0:
        return GuaranteeViolations(decisions=len(decisions))
    t_s = np.asarray(t_s, dtype=np.float64)
    # Over the whole span: one step of epoch seconds carries float rounding of ~1e-7 s.
    dt = float(t_s[-1] - t_s[0]) / (n - 1) if n > 1 else 0.01
    safety = _safety(scenario, t_s, eta, motions)
    # Rows by time from the first state; a decision before it is judged from the first.
    t0_ns = round(float(t_s[0]) * NS_PER_S)
    rows = [min(max(round((d.t_ns - t0_ns) / NS_PER_S / dt), 0), n - 1) for d in decisions]
    out: dict[str, int] = dict.fromkeys(
        ("inflated_obstacle", "hull_contacts", "hull_outside_arena", "intervals", "tube_exits",
         "successor_misses", "value_not_decreasing", "late_intervals", "estimation_misses"), 0)
    _count_safety(safety, rows, out)
    worst: dict[str, float] = {
        "worst_inflated_depth_m": max(float(safety.inflated_depth.max()), 0.0),
        "worst_hull_penetration_m": float(safety.penetration.max()),
        "worst_hull_outside_m": max(float(safety.outside.max()), 0.0),
        "worst_tube_exit_m": 0.0, "worst_successor_miss_m": 0.0,
        "worst_heading_miss_rad": 0.0, "worst_late_s": 0.0, "worst_estimation_m": 0.0}
    for index, (decision, r0) in enumerate(zip(decisions, rows, strict=True)):
        controller = controllers.get(decision.controller_version)
        if controller is None or decision.cell < 0:
            continue
        grid = controller.grid
        i0, j0, k0 = (int(c) for c in np.unravel_index(decision.cell, grid.shape))
        cell = (i0, j0, k0)
        start = eta[r0]
        i, j, k = cells_of(grid, start[None, :])
        if (int(i[0]), int(j[0]), int(k[0])) != cell:
            miss = _cell_distance_m(controller, cell, start)
            worst["worst_estimation_m"] = max(worst["worst_estimation_m"], miss)
            if miss > scenario.transient.estimation_position_m:
                out["estimation_misses"] += 1
        if decision.chosen_index < 0:
            continue
        contract = DecisionContract.of(
            controller, cell, decision.chosen_index, decision.reference_index, decision.first,
            decision.staying,
        )
        out["intervals"] += 1
        r_next = rows[index + 1] if index + 1 < len(rows) else None
        _judge_interval(contract, eta, (r0, r_next), (dt, tick_s), out, worst)
    return GuaranteeViolations(decisions=len(decisions), **out, **worst)  # type: ignore[arg-type]


def _count_safety(safety: _Safety, rows: Sequence[int], out: dict[str, int]) -> None:
    """Count the intervals (between decision rows) whose true hull broke a safety rule."""
    n = len(safety.penetration)
    for a, b in pairwise([0, *rows, n]):
        if b <= a:
            continue
        out["inflated_obstacle"] += bool((safety.inflated_depth[a:b] >= 0.0).any())
        out["hull_contacts"] += bool((safety.penetration[a:b] > 0.0).any())
        out["hull_outside_arena"] += bool((safety.outside[a:b] > 0.0).any())


def _judge_interval(
    contract: DecisionContract,
    eta: FloatArray,
    rows: tuple[int, int | None],
    times: tuple[float, float],
    out: dict[str, int],
    worst: dict[str, float],
) -> None:
    """Judge one interval on the true poses eta (N, 3): time, tube, successor, descent.

    Args:
        contract: The decision's contract.
        eta: True poses.
        rows: The decision's row and the next decision's (None: the last decision).
        times: The true states' spacing dt and the loop period tick (s).
        out: Counts, added to.
        worst: Worst sizes, raised.
    """
    n = len(eta)
    r0, nxt = rows
    dt, tick_s = times
    r_next = n - 1 if nxt is None else nxt
    r_tau = r0 + round(contract.tau_s / dt)
    if nxt is not None:
        late_s = (r_next - r0) * dt - contract.tau_s
        if late_s > contract.late_s + tick_s / 2:
            out["late_intervals"] += 1
            worst["worst_late_s"] = max(worst["worst_late_s"], late_s)
        elif late_s > 0.0:
            r_tau = r_next  # a late tick within the budget: judge the real end
    span = eta[r0 : min(r_tau, r_next, n - 1) + 1]
    exits = ~contract.in_tube(span)
    if exits.any():
        out["tube_exits"] += 1
        worst["worst_tube_exit_m"] = max(
            worst["worst_tube_exit_m"], float(contract.tube_distance_m(span[exits]).max()))
    if r_tau > r_next or r_tau >= n:
        return  # the run or a new decision cut the interval short: no end to judge
    end = eta[r_tau : r_tau + 1]
    if not contract.in_successor(end)[0]:
        out["successor_misses"] += 1
        worst["worst_successor_miss_m"] = max(
            worst["worst_successor_miss_m"], float(contract.successor_distance_m(end)[0]))
        worst["worst_heading_miss_rad"] = max(
            worst["worst_heading_miss_rad"], float(contract.heading_distance_rad(end)[0]))
    if not contract.value_decreases(end)[0]:
        out["value_not_decreasing"] += 1


def judge_outcome(spec: SimRunSpec, outcome: SimOutcome,
                  decisions: Sequence[Decision]) -> GuaranteeViolations:
    """Judge a finished simulated run (see :func:`judge_run`) on the world's truth."""
    truth = outcome.sim.truth()
    # The world's motions: the scenario's [[simulated_motion]] and the spec's together.
    return judge_run(outcome.scenario, decisions, outcome.controllers, truth[:, 0],
                     truth[:, 1 + TR_ETA : 1 + TR_ETA + 3], motions=outcome.sim.config.motions,
                     tick_s=1.0 / spec.loop.loop_hz)


def judged_run(spec: SimRunSpec, select: Select | None = None
               ) -> tuple[RunSummary, GuaranteeViolations]:
    """Run `spec` in simulation (in memory) and judge it; picklable for a process pool.

    `select`: the choice among the safe inputs; None: the spec's policy (``select``).
    """
    log = MemoryLog()
    outcome = simulate(spec, log=log, select=select)
    return outcome.summary, judge_outcome(spec, outcome, log.decisions)
