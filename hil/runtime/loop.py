"""The control loop: one stack, any world.

Each tick (20 Hz by default) the loop drains the pose and IMU feeds into the
observer (:mod:`hil.runtime.feed`), watches the obstacle feed and the re-synthesis
worker (:mod:`hil.runtime.controller_slot`), takes a symbolic decision every
`decision_period_s` (one call, :meth:`SymbolicController.decide`; what carries from
one decision to the next is :mod:`hil.runtime.decision_chain`), runs the velocity
controller and the allocator, sends the thruster command and records all of it; a
stop brakes to rest first (:mod:`hil.runtime.stopping`). The runtime
monitor (:mod:`hil.runtime.monitor`) holds every tick's estimate to the contract of
the decision in force; a tube exit is answered with a first decision at once. Faults have
one defined behaviour each (:class:`hil.runtime.events.EventCode`). Its settings
are :class:`hil.runtime.settings.LoopConfig`, what it counts
:class:`hil.runtime.stats.RunStats`.
"""

from __future__ import annotations

from dataclasses import dataclass

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
from hil.core.records import EventLevel
from hil.core.samples import ThrusterCommand
from hil.runtime.controller_slot import ControllerSlot, Swap
from hil.runtime.decider import Decider
from hil.runtime.decision_chain import DecisionChain
from hil.runtime.events import EventCode
from hil.runtime.feed import SensorFeed
from hil.runtime.mode import Mode
from hil.runtime.monitor import Monitor
from hil.runtime.protocols import LowLevel, Observer, RunLog, SymbolicController
from hil.runtime.report_age import ReportAgeBudget
from hil.runtime.resynthesis import Resynthesizer, VesselState
from hil.runtime.settings import LoopConfig
from hil.runtime.stats import RunStats
from hil.runtime.stopping import Stopping


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
            error (m), the tolerance of the runtime monitor (:mod:`hil.runtime.monitor`).
        report_ages: The report age each controller is solved for
            (:class:`~hil.runtime.report_age.ReportAgeBudget`; see
            :class:`~hil.runtime.controller_slot.ControllerSlot`). None: obstacles are
            fixed between layouts, solved for a report age of 1 s (which grows nothing).
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
        self.low_level = low_level
        self.log = log
        self.config = config or LoopConfig()
        self.report_ages = report_ages or ReportAgeBudget(1.0, tracks=False)
        self.stats = RunStats()
        self.mode = Mode.WAITING
        self._start_ns = self.stats.start_ns = world.clock.now_ns()
        self.slot = ControllerSlot(
            world.obstacles, resynthesizer, self.report_ages, log, self.stats, self._event,
            self.config.resynthesis_period_s, self._start_ns,
        )  # fmt: skip
        """The controller in force and the obstacle report it relies on."""
        self.feed = SensorFeed(world.pose, world.imu, observer, log, self.stats, self._event,
                               self.config, self._start_ns)  # fmt: skip
        """The sensors into the observer: refusals, the pose's age, the filter settling."""
        self.stopping = Stopping(self.stats, self._event)
        """Why the run stops, and the braking after it."""
        chain = DecisionChain(Monitor(estimation_position_m, 1.0 / self.config.loop_hz))
        self.decider = Decider(self.slot, chain, (select, wait_select), log, self.stats,
                               self._event, self.stopping, self.config, scenario_hash,
                               self.report_ages.tracks)  # fmt: skip
        """The symbolic decisions and the velocity reference they set."""
        self.decider.progress.start_ns = self._start_ns
        self._sink_failures = 0  # consecutive

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

    @property
    def observer(self) -> Observer:
        """The state observer (:attr:`feed`'s)."""
        return self.feed.observer

    @observer.setter
    def observer(self, observer: Observer) -> None:
        self.feed.observer = observer

    @property
    def monitor(self) -> Monitor:
        """The runtime monitor (the decider's)."""
        return self.decider.chain.monitor

    def request_stop(self, reason: str) -> None:
        """Ask the loop to stop at the next tick (safe from a signal handler).

        The vessel brakes to rest under the low level (:attr:`Mode.BRAKING`); a second
        request while braking cuts the thrust at once.
        """
        self.stopping.request(reason)

    def run(self) -> RunStats:
        """Tick until docked or stopped; thrusters are zeroed on the way out."""
        clock = self.world.clock
        period = self.config.period_ns
        next_tick = clock.now_ns()
        # The run (and its time limit) starts now, after any warm-up since construction.
        self._start_ns = self.stats.start_ns = self.slot.start_ns = next_tick
        self.feed.start_ns = self.decider.progress.start_ns = next_tick
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
        self.feed.ingest(t_ns)
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
        self.feed.estimating(t_ns)
        self.mode = self.decider.tick(t_ns, eta_hat, nu_hat, self.feed.settled(t_ns), self.mode)
        if self.stopping.abort is not None:
            # A decision of this tick aborted (any earlier abort stopped the tick above):
            # braking starts now, this tick's command too.
            self._stop(t_ns, EventCode.ABORTED, self.stopping.abort)
            if self.mode is Mode.BRAKING:
                self._fly(t_ns, eta_hat, nu_hat)
            return
        if self.mode is Mode.WAITING:
            self._send(ThrusterCommand.zero(t_ns))
            return
        self._fly(t_ns, eta_hat, nu_hat)

    # -- steps of a tick ----------------------------------------------------------------

    def _event(self, t_ns: int, level: EventLevel, code: EventCode, text: str) -> None:
        self.log.event(t_ns, level, code.value, text)

    def _check_estimate(self, t_ns: int) -> None:
        """Abort (a safe stop) once the observer's estimate broke its noise model."""
        if self.mode in (Mode.STOPPED, Mode.DOCKED):
            return
        breach = self.feed.new_breach()
        if breach is None:
            return
        self.stats.estimate_inconsistent_ns = breach.t_ns
        self._event(t_ns, EventLevel.ERROR, EventCode.ESTIMATE_INCONSISTENT, breach.text())
        if self.mode is not Mode.BRAKING and self.stopping.abort is None:
            self.stopping.abort = (
                "the estimate broke its noise model: the estimation bound no longer holds"
            )

    def _vessel_state(self) -> VesselState | None:
        estimate = self.observer.estimate()
        return self.decider.chain.vessel_state(None if estimate is None else estimate[0])

    def _swap_controller(self, t_ns: int) -> None:
        """Take what the re-synthesis returned: the first controller starts the run."""
        swap, why = self.slot.swap(t_ns)
        if swap is Swap.IN_FORCE and self.mode is Mode.WAITING:
            self.mode = Mode.RUNNING
            self.decider.next_ns = t_ns
        elif swap is Swap.LOST:
            self.stopping.abort = why

    def _check_stop(self, t_ns: int) -> bool:
        due = self.stopping.due(t_ns, self._start_ns, self.config.max_duration_s)
        if due is not None:
            self._stop(t_ns, *due)
        return due is not None

    def _stop(self, t_ns: int, code: EventCode, text: str) -> None:
        """End the run: brake to rest under the low level, or cut thrust where it cannot.

        Braking needs only the estimate and the low level, so a vessel still waiting for
        its first controller (a moving start) is braked too. Without a pose (holding on a
        lost pose, no estimate yet) it cannot brake: thrust goes to zero at once, as it
        already is.
        """
        self.stats.end_reason = text
        self.stats.aborted = code is EventCode.ABORTED
        level = EventLevel.ERROR if code is not EventCode.STOPPED else EventLevel.INFO
        self._event(t_ns, level, code, text)
        if self.mode is Mode.HOLD or self.observer.estimate() is None:
            self._cut(t_ns)
            return
        self.mode = Mode.BRAKING
        self.stopping.start_braking(t_ns)
        self.decider.stop_reference()

    def _fly(self, t_ns: int, eta_hat: FloatArray, nu_hat: FloatArray) -> None:
        """Step the low level toward the velocity reference in force; record the tick."""
        nu_ref = self.decider.nu_ref
        out = self.low_level.step(nu_ref, nu_hat, t_ns)
        self.log.velocity_reference(t_ns, nu_ref)
        self.log.force(t_ns, out.tau)
        self._send(out.command)
        self.stats.t_ns.append(t_ns)
        self.stats.eta_hat.append(eta_hat)
        self.stats.nu_hat.append(nu_hat)
        self.stats.nu_ref.append(nu_ref.copy())

    def _cut(self, t_ns: int) -> None:
        """Thrusters to zero and the run over."""
        self.mode = Mode.STOPPED
        self._send(ThrusterCommand.zero(t_ns))

    def _brake(self, t_ns: int) -> None:
        """One tick of braking: the low level holds velocity zero until at rest."""
        feed = self.feed
        estimate = self.observer.estimate()
        pose_ok = estimate is not None and feed.last_pose_ns is not None
        if self.stopping.cut_short(t_ns, pose_ok and not feed.pose_stale(t_ns)):
            self._cut(t_ns)
            return
        assert estimate is not None
        self.log.estimate(t_ns, *estimate)
        if self.stopping.brake(t_ns, estimate[1]):
            self._fly(t_ns, *estimate)
        else:
            self._cut(t_ns)

    def _pose_is_stale(self, t_ns: int) -> bool:
        stale = self.feed.pose_stale(t_ns)
        if not stale and self.mode is Mode.HOLD:
            self.mode = Mode.RUNNING if self.controller is not None else Mode.WAITING
            self.decider.next_ns = t_ns
            self.feed.settle_again()  # the filter settles again before deciding
            self._event(t_ns, EventLevel.INFO, EventCode.POSE_BACK, "pose feed is back")
        return stale

    def _hold(self, t_ns: int) -> None:
        if self.mode is not Mode.HOLD:
            self.stats.pose_losses += 1
            self._event(
                t_ns, EventLevel.ERROR, EventCode.POSE_LOST,
                f"no pose for more than {self.config.pose_timeout_s} s; thrusters to zero",
            )  # fmt: skip
            self.mode = Mode.HOLD
            self.decider.chain.restart()
            self.low_level.reset()
        self._send(ThrusterCommand.zero(t_ns))

    def _send(self, command: ThrusterCommand) -> None:
        try:
            self.world.thrusters.send(command)
        except ThrusterSinkError as err:
            self.stats.thruster_failures += 1
            self._sink_failures += 1
            self._event(command.t_ns, EventLevel.ERROR, EventCode.THRUSTER_FAILURE, str(err))
            if self._sink_failures >= self.config.max_thruster_failures and (
                self.mode is not Mode.STOPPED
            ):
                self.mode = Mode.STOPPED
                self.stats.end_reason = f"thruster sink failed {self._sink_failures} times in a row"
            return
        self._sink_failures = 0
        self.log.thrusters(command)
