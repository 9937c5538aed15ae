"""The control loop: one stack, any world.

Each tick (20 Hz by default) the loop drains the pose and IMU feeds into the
observer, watches the obstacle feed and the re-synthesis worker, takes a
symbolic decision every `decision_period_s`, runs the velocity controller and
the allocator, sends the thruster command and records all of it. The runtime
monitor (:mod:`hil.runtime.monitor`) holds every tick's estimate to the contract of
the decision in force; a tube exit is answered with a first decision at once. Faults have
one defined behaviour each (:class:`hil.runtime.events.EventCode`). Its settings
are :class:`hil.runtime.settings.LoopConfig`, what it counts
:class:`hil.runtime.stats.RunStats`.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from hil.adapters.interfaces import (
    Clock,
    ImuSource,
    ObstacleSource,
    PoseSource,
    ThrusterSink,
    ThrusterSinkError,
)
from hil.controllers.symbolic import Select, wait_slowest
from hil.core.arrays import FloatArray
from hil.core.records import Decision, EventLevel
from hil.core.samples import ImuSample, PoseSample, ThrusterCommand
from hil.core.transient import LATE_S, START_PERIODS
from hil.runtime.controller_slot import ControllerSlot, Swap
from hil.runtime.events import EventCode
from hil.runtime.monitor import Monitor, Violation
from hil.runtime.protocols import LowLevel, Observer, RunLog, SymbolicController
from hil.runtime.report_age import ReportAgeBudget
from hil.runtime.resynthesis import Resynthesizer, VesselState
from hil.runtime.settings import NS_PER_S, LoopConfig
from hil.runtime.stats import RunStats


class Mode(enum.Enum):
    """What the loop is doing."""

    WAITING = "waiting"
    """No controller yet: thrusters at zero."""
    RUNNING = "running"
    """Following the symbolic controller."""
    HOLD = "hold"
    """Pose lost: thrusters at zero until it is back."""
    AT_TARGET = "at_target"
    """In the target set: holding position with a zero velocity reference."""
    DOCKED = "docked"
    """Held the target long enough: the run is over."""
    BRAKING = "braking"
    """Stopping (an abort, an operator's stop, a timeout): velocity reference zero under
    the low level until the vessel is at rest, then thrusters at zero (STOPPED)."""
    STOPPED = "stopped"
    """Stopped for good, thrusters at zero (at rest after braking, a thruster fault, a
    stop without a pose or a second stop request)."""


REST_SPEED_MPS = 0.01
"""At rest: |u| and |v| of the estimate at most this (m/s)..."""
REST_YAW_RATE_RADPS = 0.01
"""... and |r| at most this (rad/s) ..."""
REST_HOLD_S = 1.0
"""... for this long (s): then braking ends with thrusters at zero."""
MAX_BRAKE_S = 8.0
"""Braking longer than this (s) ends with thrusters at zero and a warning: from the
fastest input (0.2 m/s) the vessel is at rest within about 4 s under the low level."""


@dataclass(frozen=True, slots=True)
class World:
    """Everything the stack reads and writes, from one backend."""

    clock: Clock
    pose: PoseSource
    imu: ImuSource
    obstacles: ObstacleSource
    thrusters: ThrusterSink


class Runtime:
    """Runs the stack against a world until docked, stopped or timed out.

    Args:
        world: Clock and adapters of one backend.
        observer: State observer.
        low_level: Velocity controller and thrust allocation.
        resynthesizer: Worker that turns obstacle layouts into controllers.
        select: The choice among the safe inputs (:data:`~hil.controllers.symbolic.Select`:
            the listed inputs as options -> a row); the paper's J in a plain run.
        log: Where everything is recorded.
        config: Timing and thresholds.
        scenario_hash: Identifies the scenario in every decision record.
        estimation_position_m: The transient budget's bound on the estimate's position
            error (m), the tolerance of the runtime monitor's tube judge
            (:mod:`hil.runtime.monitor`).
        report_ages: The report age each controller is solved for
            (:class:`~hil.runtime.report_age.ReportAgeBudget`: the scenario's
            ``max_report_age_s``, or measured). With obstacles that move, a decision may
            rely on its controller's report while it is at most that old: a fresher report
            of moved obstacles is re-synthesized, one of the same shapes renews the report
            time the controller relies on (no synthesis), and an older one stops the
            vessel (``obstacles_stale``). None: obstacles are fixed between layouts, solved
            for a report age of 1 s (which grows nothing).
        wait_select: The choice among the safety controller's inputs where docking is
            not winning (a moving obstacle closed the passage): the vessel stays safe and
            waits, and docks once the state wins again. The slowest by J by default.
    """

    def __init__(
        self,
        world: World,
        observer: Observer,
        low_level: LowLevel,
        resynthesizer: Resynthesizer[SymbolicController],
        select: Select,
        log: RunLog,
        config: LoopConfig | None = None,
        scenario_hash: str = "",
        estimation_position_m: float = 0.0,
        report_ages: ReportAgeBudget | None = None,
        wait_select: Select = wait_slowest,
    ) -> None:
        self.world = world
        self.observer = observer
        self.low_level = low_level
        self.select = select
        self.wait_select = wait_select
        self.log = log
        self.config = config or LoopConfig()
        self.scenario_hash = scenario_hash
        self.report_ages = report_ages or ReportAgeBudget(1.0, tracks=False)
        self.stats = RunStats()
        self.monitor = Monitor(estimation_position_m, 1.0 / self.config.loop_hz)
        self.mode = Mode.WAITING
        self._start_ns = world.clock.now_ns()
        self.slot = ControllerSlot(
            world.obstacles, resynthesizer, self.report_ages, log, self.stats, self._event,
            self.config.resynthesis_period_s, self._start_ns,
        )  # fmt: skip
        """The controller in force and the obstacle report it relies on."""
        self._last_pose_ns: int | None = None
        self._next_decision_ns = 0
        self._last_choice_ns: int | None = None  # when the input in force was chosen
        self._nu_ref = np.zeros(3)
        self._previous_input = np.zeros(3)
        # Input-grid index of the reference in force; None: the next decision starts
        # afresh (start, or after a stop or a hold) from the estimated velocity.
        self._reference_index: int | None = None
        # First decisions still to take: a start counts START_PERIODS periods (budget
        # class START), the vessel possibly moving and its thrusters still idle.
        self._first_left = START_PERIODS
        self._estimating_since_ns: int | None = None
        self._consecutive_sink_failures = 0
        self.stats.start_ns = self._start_ns
        self._target_since_ns = 0
        self._stop_requested: str | None = None
        self._stop_requests = 0
        self._requests_at_brake = 0
        self._brake_since_ns = 0
        self._rest_since_ns: int | None = None
        self._abort: str | None = None
        self._estimate_breach = False
        self._not_winning_before = False
        self._staying = False  # the last decision was the safety controller's

    # -- public -----------------------------------------------------------------------

    @property
    def controller(self) -> SymbolicController | None:
        """The controller in force (:attr:`slot`)."""
        return self.slot.controller

    @property
    def resynthesizer(self) -> Resynthesizer[SymbolicController]:
        """The worker that turns obstacle layouts into controllers (:attr:`slot`'s)."""
        return self.slot.resynthesizer

    @property
    def controller_version(self) -> int:
        """The version of the controller in force."""
        return self.slot.version

    def request_stop(self, reason: str) -> None:
        """Ask the loop to stop at the next tick (safe from a signal handler).

        The vessel brakes to rest under the low level (:attr:`Mode.BRAKING`); a second
        request while braking cuts the thrust at once.
        """
        self._stop_requested = reason
        self._stop_requests += 1

    def run(self) -> RunStats:
        """Tick until docked or stopped; thrusters are zeroed on the way out."""
        clock = self.world.clock
        period = self.config.period_ns
        next_tick = clock.now_ns()
        # The run (and its time limit) starts now, after any warm-up since construction.
        self._start_ns = self.stats.start_ns = self.slot.start_ns = next_tick
        try:
            while self.mode not in (Mode.DOCKED, Mode.STOPPED):
                now = clock.now_ns()
                self.stats.tick_wall_ns.append(now)
                if now - next_tick > period:
                    # More than a period late: skip the missed ticks instead of bunching them.
                    self.stats.overruns += 1
                    next_tick = now
                self.tick(now)
                next_tick += period
                clock.sleep_until(next_tick)
        finally:
            self.stats.end_ns = clock.now_ns()
            self._send(ThrusterCommand.zero(self.stats.end_ns))
        return self.stats

    def tick(self, t_ns: int) -> None:
        """Run one loop iteration at time `t_ns`."""
        self._ingest(t_ns)
        self._check_estimate(t_ns)
        self.slot.watch(t_ns, self.mode is Mode.BRAKING, self._vessel_state)
        self._swap_controller(t_ns)
        if self.mode is not Mode.BRAKING and self._check_stop(t_ns) and self.mode is Mode.STOPPED:
            return
        if self.mode is Mode.BRAKING:  # from this tick on: every tick commands the brake
            self._brake(t_ns)
            return
        estimate = self.observer.estimate()
        if self._pose_is_stale(t_ns):
            self._hold(t_ns)
            return
        if estimate is None:  # the feed is coming up: wait with thrusters at zero
            self._send(ThrusterCommand.zero(t_ns))
            return
        eta_hat, nu_hat = estimate
        self.log.estimate(t_ns, eta_hat, nu_hat)
        if self._estimating_since_ns is None:
            self._estimating_since_ns = t_ns
        if t_ns >= self._next_decision_ns and self._observer_settled(t_ns):
            self.slot.take_early(
                t_ns, eta_hat, self._reference_index if self._first_left == 0 else None
            )
            self._check_late(t_ns)
            # A stale obstacle report leaves the decision due: taken once a fresher one is in.
            if self._ready_to_decide(t_ns):
                for violation in self.monitor.at_decision(t_ns, eta_hat):
                    self._violation(t_ns, violation)
                if self._decide_or_stop(t_ns, eta_hat, nu_hat):
                    return
        else:
            exit_ = self.monitor.tick(t_ns, eta_hat)
            if exit_ is not None:
                # The guarantee no longer covers this interval: decide afresh, as a first
                # decision from the estimated velocity, now.
                self._violation(t_ns, exit_)
                self._reference_index = None
                if not self._ready_to_decide(t_ns):
                    self._next_decision_ns = t_ns  # decide once a fresher report is in
                elif self._decide_or_stop(t_ns, eta_hat, nu_hat):
                    return
        if self.mode is Mode.WAITING:
            self._send(ThrusterCommand.zero(t_ns))
            return
        self._fly(t_ns, eta_hat, nu_hat)

    # -- steps of a tick ----------------------------------------------------------------

    def _event(self, t_ns: int, level: EventLevel, code: EventCode, text: str) -> None:
        self.log.event(t_ns, level, code.value, text)

    def _violation(self, t_ns: int, v: Violation) -> None:
        """Count and record one broken promise of a decision (runtime monitor)."""
        s = self.stats
        if v.code is EventCode.TUBE_EXIT:
            s.tube_exits += 1
            s.worst_tube_exit_m = max(s.worst_tube_exit_m, v.size)
        elif v.code is EventCode.SUCCESSOR_MISS:
            s.successor_misses += 1
            s.worst_successor_miss_m = max(s.worst_successor_miss_m, v.size)
        else:
            s.value_not_decreasing += 1
        self._event(t_ns, v.level, v.code, v.text)

    def _ingest(self, t_ns: int) -> None:
        # Fuse both feeds in measurement-time order: when the loop lags, draining all
        # poses before all IMU samples would hand the filter IMU samples from its past.
        samples: list[PoseSample | ImuSample] = [*self.world.pose.poll(), *self.world.imu.poll()]
        samples.sort(key=lambda s: s.t_ns)
        for sample in samples:
            if isinstance(sample, PoseSample):
                self.log.pose(sample)
                if self.observer.update_pose(sample):
                    last = self._last_pose_ns
                    self._last_pose_ns = sample.t_ns if last is None else max(last, sample.t_ns)
                else:
                    self._reject(t_ns, f"pose at t={sample.t_ns} ns")
            else:
                self.log.imu(sample)
                if not self.observer.update_imu(sample):
                    self._reject(t_ns, f"imu at t={sample.t_ns} ns")

    def _check_estimate(self, t_ns: int) -> None:
        """Abort (a safe stop) once the observer's estimate broke its noise model."""
        if self._estimate_breach or self.mode in (Mode.STOPPED, Mode.DOCKED):
            return
        breach = self.observer.breach()
        if breach is None:
            return
        self._estimate_breach = True
        self.stats.estimate_inconsistent_ns = breach.t_ns
        self._event(t_ns, EventLevel.ERROR, EventCode.ESTIMATE_INCONSISTENT, breach.text())
        if self.mode is not Mode.BRAKING and self._abort is None:
            self._abort = "the estimate broke its noise model: the estimation bound no longer holds"

    def _reject(self, t_ns: int, what: str) -> None:
        self.stats.rejected_samples += 1
        # Log the first few and then every 100th, so a flood cannot swamp the log.
        n = self.stats.rejected_samples
        if n <= 5 or n % 100 == 0:
            self._event(
                t_ns,
                EventLevel.WARN,
                EventCode.SAMPLE_REJECTED,
                f"observer rejected {what} ({n} so far)",
            )

    def _vessel_state(self) -> VesselState | None:
        """Return the state an early controller must cover: mid-run, the reference in force.

        None when the next decision is a first one (start, after a stop or a hold): a
        first decision may take any input into the winning set at any value, which only
        the full solve knows.
        """
        if self._reference_index is None or self._first_left > 0:
            return None
        estimate = self.observer.estimate()
        if estimate is None:
            return None
        return VesselState(estimate[0].copy(), self._reference_index)

    def _swap_controller(self, t_ns: int) -> None:
        """Take what the re-synthesis returned: the first controller starts the run."""
        swap, why = self.slot.swap(t_ns)
        if swap is Swap.IN_FORCE and self.mode is Mode.WAITING:
            self.mode = Mode.RUNNING
            self._next_decision_ns = t_ns
        elif swap is Swap.LOST:
            self._abort = why

    def _ready_to_decide(self, t_ns: int) -> bool:
        """Return whether a decision may be taken now; else the reference goes to zero.

        A first decision under an early controller waits for the full solve (it may take
        any input into the winning set, at any value); a decision whose obstacle report
        is too old waits for a fresher one (:meth:`_obstacles_fresh`).
        """
        if self.slot.in_force_early and (self._reference_index is None or self._first_left > 0):
            self._reference_index = None
            self.monitor.clear()
            self._set_reference(np.zeros(3))
            return False
        return self._obstacles_fresh(t_ns)

    def _check_late(self, t_ns: int) -> None:
        """Name a decision due later than tau + late after the input in force was chosen.

        The budgets bound an interval of at most tau + :data:`LATE_S`; past that the
        input in force has gone beyond what its decision assumed (a stalled loop). The
        decision is then a first one, from the estimated velocity, and the interval's
        successor is not judged (its premise broke; the event says so, with its size).
        """
        chosen = self._last_choice_ns
        if chosen is None or self._reference_index is None:
            return
        held_s = (t_ns - chosen) / NS_PER_S
        allowed_s = self.config.decision_period_s + LATE_S
        if held_s <= allowed_s:
            return
        s = self.stats
        s.late_intervals += 1
        s.worst_late_s = max(s.worst_late_s, held_s - allowed_s)
        self._event(
            t_ns,
            EventLevel.ERROR,
            EventCode.LATE_INTERVAL,
            f"the input chosen at t={chosen} ns was held {held_s:.3f} s, past tau + late = "
            f"{allowed_s:g} s by {held_s - allowed_s:.3f} s (the loop stalled): no budget "
            "covers it; deciding at once as a first decision",
        )
        self._reference_index = None
        self.monitor.clear()

    def _check_stop(self, t_ns: int) -> bool:
        if self._abort is not None:
            self._stop(t_ns, EventCode.ABORTED, self._abort)
            return True
        if self._stop_requested is not None:
            self._stop(t_ns, EventCode.STOPPED, self._stop_requested)
            return True
        if t_ns - self._start_ns > self.config.max_duration_s * NS_PER_S:
            self._stop(
                t_ns, EventCode.TIMEOUT, f"not docked after {self.config.max_duration_s:.0f} s"
            )
            return True
        return False

    def _stop(self, t_ns: int, code: EventCode, text: str) -> None:
        """End the run: brake to rest under the low level, or cut thrust where it cannot.

        Braking needs only the estimate and the low level, so a vessel still waiting for
        its first controller (a moving start) is braked too. Without a pose (holding on a
        lost pose, no estimate yet) it cannot brake: thrust goes to zero at once, as it
        already is.
        """
        self.stats.end_reason = text
        self.stats.aborted = code is EventCode.ABORTED
        self._event(
            t_ns, EventLevel.ERROR if code is not EventCode.STOPPED else EventLevel.INFO, code, text
        )
        if self.mode is Mode.HOLD or self.observer.estimate() is None:
            self._cut(t_ns)
            return
        self.mode = Mode.BRAKING
        self._brake_since_ns = t_ns
        self._rest_since_ns = None
        self._requests_at_brake = self._stop_requests
        self._reference_index = None
        self.monitor.clear()
        self._set_reference(np.zeros(3))

    def _fly(self, t_ns: int, eta_hat: FloatArray, nu_hat: FloatArray) -> None:
        """Step the low level toward the velocity reference in force; record the tick."""
        out = self.low_level.step(self._nu_ref, nu_hat, t_ns)
        self.log.velocity_reference(t_ns, self._nu_ref)
        self.log.force(t_ns, out.tau)
        self._send(out.command)
        self.stats.t_ns.append(t_ns)
        self.stats.eta_hat.append(eta_hat)
        self.stats.nu_hat.append(nu_hat)
        self.stats.nu_ref.append(self._nu_ref.copy())

    def _decide_or_stop(self, t_ns: int, eta_hat: FloatArray, nu_hat: FloatArray) -> bool:
        """Decide now and schedule the next decision; return True when the decision aborted.

        An abort brakes from this tick on, this tick's command included.
        """
        self._decide(t_ns, eta_hat, nu_hat)
        self._next_decision_ns = t_ns + round(self.config.decision_period_s * NS_PER_S)
        if self._abort is None:
            return False
        self._stop_after_decision(t_ns, eta_hat, nu_hat)
        return True

    def _stop_after_decision(self, t_ns: int, eta_hat: FloatArray, nu_hat: FloatArray) -> None:
        """Abort after a decision of this tick: braking starts now, this tick's command too."""
        assert self._abort is not None
        self._stop(t_ns, EventCode.ABORTED, self._abort)
        if self.mode is Mode.BRAKING:
            self._fly(t_ns, eta_hat, nu_hat)

    def _cut(self, t_ns: int) -> None:
        """Thrusters to zero and the run over."""
        self.mode = Mode.STOPPED
        self._send(ThrusterCommand.zero(t_ns))

    def _brake(self, t_ns: int) -> None:
        """One tick of braking: the low level holds velocity zero until at rest.

        Thrust is cut at once on a second stop request (the operator's emergency stop),
        a lost pose (the loop cannot brake blind) or after :data:`MAX_BRAKE_S`.
        """
        since_s = (t_ns - self._brake_since_ns) / NS_PER_S
        if self._stop_requests > self._requests_at_brake:
            self._event(t_ns, EventLevel.WARN, EventCode.STOPPED,
                        f"{self._stop_requested} again while braking: thrust cut at once")
            self._cut(t_ns)
            return
        estimate = self.observer.estimate()
        last = self._last_pose_ns
        if estimate is None or last is None or t_ns - last > self.config.pose_timeout_s * NS_PER_S:
            self._event(t_ns, EventLevel.ERROR, EventCode.POSE_LOST,
                        f"no pose while braking ({since_s:.1f} s in): thrust cut")
            self._cut(t_ns)
            return
        eta_hat, nu_hat = estimate
        self.log.estimate(t_ns, eta_hat, nu_hat)
        resting = bool(
            abs(nu_hat[0]) <= REST_SPEED_MPS and abs(nu_hat[1]) <= REST_SPEED_MPS
            and abs(nu_hat[2]) <= REST_YAW_RATE_RADPS
        )
        if not resting:
            self._rest_since_ns = None
        elif self._rest_since_ns is None:
            self._rest_since_ns = t_ns
        if self._rest_since_ns is not None and (
            t_ns - self._rest_since_ns >= REST_HOLD_S * NS_PER_S
        ):
            self.stats.brake_s = since_s
            self._event(t_ns, EventLevel.INFO, EventCode.AT_REST,
                        f"at rest {since_s:.1f} s after the stop: thrusters to zero")
            self._cut(t_ns)
            return
        if since_s > MAX_BRAKE_S:
            self.stats.brake_s = since_s
            self._event(t_ns, EventLevel.WARN, EventCode.AT_REST,
                        f"not at rest after {MAX_BRAKE_S:g} s of braking (estimate "
                        f"{np.round(nu_hat, 3).tolist()}): thrusters to zero")
            self._cut(t_ns)
            return
        self._fly(t_ns, eta_hat, nu_hat)

    def _obstacles_fresh(self, t_ns: int) -> bool:
        """Return whether a decision may rely on the controller's obstacle report; else stop.

        Too old a report (:meth:`ControllerSlot.fresh`): the velocity reference goes to
        zero and the next decision, once a fresher report is in, is a first decision.
        """
        if self.slot.fresh(t_ns):
            return True
        self._reference_index = None
        self.monitor.clear()
        self._set_reference(np.zeros(3))
        return False

    def _observer_settled(self, t_ns: int) -> bool:
        """Return whether a decision may be taken now (a first one waits for the filter)."""
        if self._reference_index is not None or self._estimating_since_ns is None:
            return self._reference_index is not None
        settle_ns = round(self.config.observer_settle_s * NS_PER_S)
        return t_ns - self._estimating_since_ns >= settle_ns

    def _pose_is_stale(self, t_ns: int) -> bool:
        timeout_ns = self.config.pose_timeout_s * NS_PER_S
        # Before the first pose, allow one timeout from the start for the feed to come up.
        last = self._start_ns if self._last_pose_ns is None else self._last_pose_ns
        stale = t_ns - last > timeout_ns
        if not stale and self.mode is Mode.HOLD:
            self.mode = Mode.RUNNING if self.controller is not None else Mode.WAITING
            self._next_decision_ns = t_ns
            self._estimating_since_ns = None  # the filter settles again before deciding
            self._event(t_ns, EventLevel.INFO, EventCode.POSE_BACK, "pose feed is back")
        return stale

    def _hold(self, t_ns: int) -> None:
        if self.mode is not Mode.HOLD:
            self.stats.pose_losses += 1
            self._event(
                t_ns,
                EventLevel.ERROR,
                EventCode.POSE_LOST,
                f"no pose for more than {self.config.pose_timeout_s} s; thrusters to zero",
            )
            self.mode = Mode.HOLD
            self._reference_index = None
            self.monitor.clear()
            self.low_level.reset()
        self._send(ThrusterCommand.zero(t_ns))

    def _decide(self, t_ns: int, eta_hat: FloatArray, nu_hat: FloatArray) -> None:
        controller = self.controller
        self.monitor.clear()
        if controller is None:
            self._reference_index = None
            if self.mode is not Mode.WAITING:
                self._set_reference(np.zeros(3))
                self._event(
                    t_ns,
                    EventLevel.ERROR,
                    EventCode.NO_CONTROLLER,
                    "no valid controller; velocity reference zero",
                )
            return
        if self._reference_index is None:
            self._first_left = START_PERIODS
        first = self._first_left > 0
        reference = (
            controller.nearest_input(nu_hat)
            if self._reference_index is None
            else self._reference_index
        )
        answer = controller.decide(
            eta_hat, reference, first, self._previous_input, self.select, self.wait_select
        )
        cell, value, indices, chosen_index = answer.cell, answer.value, answer.inputs, answer.chosen
        self._note_staying(t_ns, answer.staying, eta_hat)
        if value == 0.0:
            self._at_target(t_ns)
        elif answer.staying:
            self.stats.staying_decisions += 1
        elif math.isinf(value):
            self.stats.not_winning_decisions += 1
            state = np.round(eta_hat, 3).tolist()
            self._event(
                t_ns,
                EventLevel.ERROR,
                EventCode.NOT_WINNING,
                f"state {state} outside the winning and the safety set; stopping",
            )
            where = "outside the grid" if cell < 0 else "outside the winning set"
            if self.stats.decisions == 0:
                self._abort = (
                    f"start {state} is {where}: no input is safe from there "
                    "(too close to an obstacle or a wall, cut off from the target, "
                    "or moving too fast to turn away in time)"
                )
            elif self._not_winning_before:
                self._abort = (
                    f"state {state} still {where} after "
                    f"{self.config.decision_period_s:g} s stopped: no safe input"
                )
        chosen = controller.inputs[chosen_index].copy() if chosen_index >= 0 else np.zeros(3)
        self._not_winning_before = math.isinf(value) and not answer.staying
        if value != 0.0 and self.mode is Mode.AT_TARGET:
            self.mode = Mode.RUNNING  # pushed out of the target: steer back in
        self._set_reference(chosen)
        if chosen_index >= 0:
            self._previous_input = chosen
        # A stop (reference zero outside the lattice step) is not budgeted: after it the
        # next decision starts afresh from the estimated velocity.
        self._reference_index = chosen_index if chosen_index >= 0 else None
        self._last_choice_ns = t_ns if chosen_index >= 0 else None
        if chosen_index >= 0:
            self._first_left = max(self._first_left - 1, 0)
            self.monitor.start(t_ns, answer.contract)
        self.stats.decisions += 1
        self.log.decision(
            Decision.from_arrays(
                t_ns,
                eta_hat,
                cell,
                value,
                math.isfinite(value),
                controller.inputs[indices],
                indices,
                chosen_index,
                self.controller_version,
                self.scenario_hash,
                chosen_input=chosen,
                reference_index=reference,
                first=first,
                report_age_s=self.slot.age_s,
                report_t_ns=-1 if self.slot.layout is None else self.slot.layout.t_ns,
            )
        )

    def _note_staying(self, t_ns: int, staying: bool, eta_hat: FloatArray) -> None:
        """Say when the vessel starts waiting on the safety controller, and when it docks on."""
        if staying == self._staying:
            return
        self._staying = staying
        state = np.round(eta_hat, 3).tolist()
        if staying:
            self.stats.docking_lost += 1
            self._event(
                t_ns, EventLevel.WARN, EventCode.DOCKING_LOST,
                f"docking is not winning from {state} (controller v{self.controller_version}): "
                "staying in the safety set, slowing, until it wins again",
            )  # fmt: skip
        else:
            self._event(
                t_ns, EventLevel.INFO, EventCode.DOCKING_BACK,
                f"docking is winning again from {state}: docking on",
            )  # fmt: skip

    def _at_target(self, t_ns: int) -> None:
        if self.stats.target_reached_ns is None:
            self.stats.target_reached_ns = t_ns
            self._event(
                t_ns,
                EventLevel.INFO,
                EventCode.TARGET_REACHED,
                f"target reached after {(t_ns - self._start_ns) / NS_PER_S:.1f} s",
            )
        if self.mode is not Mode.AT_TARGET:
            self.mode = Mode.AT_TARGET
            self._target_since_ns = t_ns
        elif t_ns - self._target_since_ns >= self.config.dock_hold_s * NS_PER_S:
            self.mode = Mode.DOCKED
            self.stats.docked_ns = t_ns
            self.stats.end_reason = "docked"
            self._event(
                t_ns,
                EventLevel.INFO,
                EventCode.DOCKED,
                f"held the target for {self.config.dock_hold_s:.0f} s",
            )

    def _set_reference(self, nu_ref: FloatArray) -> None:
        self._nu_ref = np.asarray(nu_ref, dtype=np.float64).copy()

    def _send(self, command: ThrusterCommand) -> None:
        try:
            self.world.thrusters.send(command)
        except ThrusterSinkError as err:
            self.stats.thruster_failures += 1
            self._consecutive_sink_failures += 1
            self._event(command.t_ns, EventLevel.ERROR, EventCode.THRUSTER_FAILURE, str(err))
            if (
                self._consecutive_sink_failures >= self.config.max_thruster_failures
                and self.mode is not Mode.STOPPED
            ):
                self.mode = Mode.STOPPED
                n = self._consecutive_sink_failures
                self.stats.end_reason = f"thruster sink failed {n} times in a row"
            return
        self._consecutive_sink_failures = 0
        self.log.thrusters(command)
