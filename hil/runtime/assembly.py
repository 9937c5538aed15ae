"""Wire the stack's components behind the runtime's protocols.

The observer (EKF), the velocity PID with thrust allocation, and the symbolic
controller with its re-synthesis each get a thin adapter here, so the loop in
:mod:`hil.runtime.loop` sees only :mod:`hil.runtime.protocols`'s protocols.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np

from hil.controllers.consistency import ConsistencyBreach, ConsistencyLimits, ConsistencyWatch
from hil.controllers.low_level import LowLevelController, LowLevelParams
from hil.controllers.observer import Ekf, ObserverStatus
from hil.controllers.pid import PidGains
from hil.controllers.symbolic import (
    Controller,
    NoWinningSetError,
    SymbolicAdapter,
    SymbolicProblem,
    Synthesizer,
    Watch,
)
from hil.core.arrays import FloatArray
from hil.core.samples import ImuSample, ObstacleLayout, PoseSample, ThrusterCommand
from hil.core.shapes import Rect
from hil.runtime.protocols import LowLevelOutput
from hil.runtime.resynthesis import VesselState
from hil.scenarios import Obstacle, Scenario

# A gated yaw rate is not a broken sample (robot_localization drops it quietly), and an
# IMU sample before the first pose has nothing to update yet.
_IMU_ACCEPTED = {ObserverStatus.FUSED, ObserverStatus.GATED, ObserverStatus.NOT_INITIALIZED}
_POSE_ACCEPTED = {ObserverStatus.FUSED, ObserverStatus.RESET}


class EkfObserver:
    """The EKF behind the runtime's :class:`~hil.runtime.protocols.Observer` protocol.

    Args:
        ekf: The filter; a default one if None.
        start_nu: Body velocity (u, v, r), shape (3,), the filter starts with at its
            first pose (a vessel known to be moving already); None starts at rest, as
            the filter does by itself.
        estimation_bound_m: The estimation bound the guarantee assumes (m): each
            pose's innovation is judged against it and the filter's pose noise
            (:mod:`hil.controllers.consistency`); None: not watched.
    """

    def __init__(
        self,
        ekf: Ekf | None = None,
        start_nu: FloatArray | None = None,
        estimation_bound_m: float | None = None,
    ) -> None:
        self.ekf = ekf or Ekf()
        self._start_nu = None if start_nu is None else np.asarray(start_nu, dtype=np.float64)
        self.watch = None if estimation_bound_m is None else ConsistencyWatch(
            ConsistencyLimits(estimation_bound_m, self.ekf.config.pose_std_m))
        """The consistency watch (None: not watched)."""

    def update_pose(self, sample: PoseSample) -> bool:
        """Fuse a pose; False when the filter refused it. The watch judges its innovation."""
        starting = not self.ekf.initialized
        status = self.ekf.process_pose(sample)
        if starting and self.ekf.initialized and self._start_nu is not None:
            # Restart at the pose just fused, with the known velocity (counters are kept).
            first = self.ekf.estimate()
            self.ekf.initialize(first.t_ns, first.eta, self._start_nu)
            self._start_nu = None
        if self.watch is not None:
            innovation = self.ekf.last_innovation()
            self.watch.pose(
                sample.t_ns, innovation.nis, innovation.position_m,
                gated=status in (ObserverStatus.GATED, ObserverStatus.RESET),
            )  # fmt: skip
        return status in _POSE_ACCEPTED

    def breach(self) -> ConsistencyBreach | None:
        """Return the watch's first breach of the estimation premise, if any."""
        return None if self.watch is None else self.watch.breach

    def update_imu(self, sample: ImuSample) -> bool:
        """Take an IMU sample; False when the filter refused it."""
        return self.ekf.process_imu(sample) in _IMU_ACCEPTED

    def estimate(self) -> tuple[FloatArray, FloatArray] | None:
        """Return (eta, nu) at the newest fused sample; None before the first pose.

        With the IMU at 100 Hz the filter time trails a 20-Hz tick by at most one
        sample period (10 ms), so no extra prediction is made.
        """
        if not self.ekf.initialized:
            return None
        estimate = self.ekf.estimate()
        return estimate.eta, estimate.nu


class PidAllocator:
    """The low level (velocity PID and thrust allocation) behind the ``LowLevel`` protocol.

    A thin adapter: :class:`~hil.controllers.low_level.LowLevelController` runs the
    compiled tick that the simulated closed loop runs too; this turns its output into
    a time-stamped thruster command.

    Args:
        controller: The low level (its ``params.dt_s`` must be the loop period).
    """

    def __init__(self, controller: LowLevelController) -> None:
        self.controller = controller

    def step(self, nu_ref: FloatArray, nu_hat: FloatArray, t_ns: int) -> LowLevelOutput:
        """Return the force demand and the commands that realize it."""
        out = self.controller.tick(nu_ref, nu_hat)
        u, alpha = out.commands, out.angles_rad
        command = ThrusterCommand(
            t_ns, float(u[0]), float(u[1]), float(u[2]), float(alpha[0]), float(alpha[1])
        )
        return LowLevelOutput(out.tau_n, command)

    def reset(self) -> None:
        """Forget the integrator and the allocator's null-space state."""
        self.controller.reset()


def low_level_for(loop_hz: float, gains: PidGains | None = None) -> PidAllocator:
    """Return the vessel's low level for a loop at `loop_hz` (default gains if None)."""
    params = LowLevelParams(dt_s=1.0 / loop_hz)
    return PidAllocator(
        LowLevelController(params if gains is None else replace(params, gains=gains))
    )


def obstacles_from_layout(scenario: Scenario, layout: ObstacleLayout) -> tuple[Obstacle, ...]:
    """Turn a reported layout into scenario obstacles with the scenario's inflation.

    Obstacle n keeps the name, inflation and speed bound of the scenario's obstacle n;
    extra obstacles take the largest inflation and speed bound of the scenario.
    """
    default = max((o.inflation_m for o in scenario.obstacles), default=0.0)
    fastest = max((o.max_speed_mps for o in scenario.obstacles), default=0.0)
    out = []
    for n, rect in enumerate(layout.obstacles):
        known = scenario.obstacles[n] if n < len(scenario.obstacles) else None
        out.append(
            Obstacle(
                name=known.name if known else f"obstacle{n + 1}",
                shape=Rect(rect.x_min_m, rect.x_max_m, rect.y_min_m, rect.y_max_m),
                inflation_m=known.inflation_m if known else default,
                max_speed_mps=known.max_speed_mps if known else fastest,
            )
        )
    return tuple(out)


def layout_from_scenario(scenario: Scenario, t_ns: int = 0) -> ObstacleLayout:
    """Return the scenario's real obstacles as a layout (axis-aligned bounding boxes)."""
    rects = []
    for obstacle in scenario.obstacles:
        v = obstacle.shape.vertices()
        rects.append(
            Rect(
                float(v[:, 0].min()),
                float(v[:, 0].max()),
                float(v[:, 1].min()),
                float(v[:, 1].max()),
            )
        )
    return ObstacleLayout(t_ns, tuple(rects))


@dataclass
class LayoutSolver:
    """Synthesizes a controller for a reported layout, reusing the grid's tables.

    Attributes:
        scenario: The scenario (grid, inputs, target, inflation).
        synthesizer: Holds the abstraction tables, built once per grid.
    """

    scenario: Scenario
    synthesizer: Synthesizer

    def __call__(
        self, layout: ObstacleLayout, report_age_s: float | None = None
    ) -> SymbolicAdapter:
        """Return the controller for `layout`, its moving obstacles grown for `report_age_s`.

        None: the scenario's ``max_report_age_s``.

        Raises:
            NoWinningSetError: No cell outside the target is winning.
        """
        before = self.synthesizer.sources.copy()
        controller = self.synthesizer.solve_problem(self._problem(layout, report_age_s))
        self._require_winning(controller, layout)
        return SymbolicAdapter(controller, self.synthesizer.sources.source_since(before))

    def stages(
        self, layout: ObstacleLayout, report_age_s: float, vessel: VesselState
    ) -> Iterator[tuple[SymbolicAdapter, bool]]:
        """Yield (controller, complete): first one covering `vessel` if it comes early.

        The early controller is yielded once the vessel's (cell, reference) joined
        (:meth:`Synthesizer.solve_stages`); a state outside the grid watches nothing.

        Raises:
            NoWinningSetError: No cell outside the target is winning (full solve).
        """
        problem = self._problem(layout, report_age_s)
        cell = problem.grid.cell_of(vessel.eta)
        watch = None if cell is None else Watch(cell, vessel.reference)
        before = self.synthesizer.sources.copy()
        for controller in self.synthesizer.solve_stages(problem, watch):
            complete = controller.stats.complete
            if complete:
                self._require_winning(controller, layout)
            source = self.synthesizer.sources.source_since(before)
            yield SymbolicAdapter(controller, source), complete

    def _problem(self, layout: ObstacleLayout, report_age_s: float | None) -> SymbolicProblem:
        """Return the problem of `layout`: obstacles that move grown over `report_age_s`.

        Fixed obstacles are not grown, so the age changes nothing for them (the same
        masks: the memo and the store find the same controller).
        """
        scenario = self.scenario.with_obstacles(obstacles_from_layout(self.scenario, layout))
        if report_age_s is not None:
            scenario = scenario.with_report_age(report_age_s)
        return SymbolicProblem.from_scenario(scenario)

    @staticmethod
    def _require_winning(controller: Controller, layout: ObstacleLayout) -> None:
        if not controller.has_winning_start:
            raise NoWinningSetError(
                f"no winning cell outside the target for the layout at t={layout.t_ns} ns"
            )


def warm_up_kernels(loop_hz: float = 20.0) -> None:
    """Compile (or load from numba's cache) every low-level kernel before a loop starts.

    On the vessel a first call that compiles would stall the loop for seconds;
    throwaway objects take those calls so no state of the real ones is touched.
    """
    low_level = low_level_for(loop_hz)
    low_level.step(np.zeros(3), np.zeros(3), 0)
    observer = EkfObserver()
    observer.update_pose(PoseSample(0, 0.0, 0.0, 0.0))
    observer.update_imu(ImuSample(10_000_000, 0.0, 0.0, 0.0))
    observer.update_pose(PoseSample(5_000_000, 0.0, 0.0, 0.0))  # a late one: the re-run path
    observer.estimate()
