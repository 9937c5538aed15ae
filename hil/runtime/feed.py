"""The pose and IMU feeds into the observer: fused in time order, refusals counted, the pose's age.

The loop asks the feed, every tick, to take in what arrived; whether the pose is
stale (no pose for ``pose_timeout_s``: the loop holds, thrusters at zero); whether the
filter has settled enough for a first decision (``observer_settle_s`` of estimates);
and whether the estimate broke its noise model (once per run: a safe stop).
"""

from __future__ import annotations

from collections.abc import Callable

from hil.adapters.interfaces import ImuSource, PoseSource
from hil.controllers.consistency import ConsistencyBreach
from hil.core.records import EventLevel
from hil.core.samples import ImuSample, PoseSample
from hil.runtime.events import EventCode
from hil.runtime.protocols import Observer, RunLog
from hil.runtime.settings import NS_PER_S, LoopConfig
from hil.runtime.stats import RunStats

__all__ = ["EventSink", "SensorFeed"]

EventSink = Callable[[int, EventLevel, EventCode, str], None]
"""(t_ns, level, code, text): records one runtime event."""


class SensorFeed:
    """What the loop knows of its sensors, beyond the observer's estimate.

    Args:
        pose: The pose feed.
        imu: The IMU feed.
        observer: Fuses both; refuses what it cannot use.
        log: Every sample is recorded as received.
        stats: Counts refused samples.
        event: Records the feed's events.
        config: Pose timeout and the filter's settling time.
        start_ns: The run's start: before the first pose, the feed has one timeout from
            here to come up.
    """

    def __init__(
        self,
        pose: PoseSource,
        imu: ImuSource,
        observer: Observer,
        log: RunLog,
        stats: RunStats,
        event: EventSink,
        config: LoopConfig,
        start_ns: int,
    ) -> None:
        self._pose = pose
        self._imu = imu
        self.observer = observer
        """The state observer the samples go to."""
        self._log = log
        self._stats = stats
        self._event = event
        self._timeout_ns = config.pose_timeout_s * NS_PER_S
        self._settle_ns = round(config.observer_settle_s * NS_PER_S)
        self.start_ns = start_ns
        """The run's start (ns); the loop resets it when the run starts."""
        self.last_pose_ns: int | None = None
        """Stamp of the newest pose the observer took (ns); None before the first."""
        self._estimating_since_ns: int | None = None
        self._breached = False

    def ingest(self, t_ns: int) -> None:
        """Take in every pose and IMU sample that arrived, in measurement-time order.

        When the loop lags, draining all poses before all IMU samples would hand the
        filter IMU samples from its past.
        """
        samples: list[PoseSample | ImuSample] = [*self._pose.poll(), *self._imu.poll()]
        samples.sort(key=lambda s: s.t_ns)
        for sample in samples:
            if isinstance(sample, PoseSample):
                self._log.pose(sample)
                if self.observer.update_pose(sample):
                    last = self.last_pose_ns
                    self.last_pose_ns = sample.t_ns if last is None else max(last, sample.t_ns)
                else:
                    self._reject(t_ns, f"pose at t={sample.t_ns} ns")
            else:
                self._log.imu(sample)
                if not self.observer.update_imu(sample):
                    self._reject(t_ns, f"imu at t={sample.t_ns} ns")

    def pose_stale(self, t_ns: int) -> bool:
        """Return whether no pose came for longer than the timeout (ns clock `t_ns`)."""
        last = self.start_ns if self.last_pose_ns is None else self.last_pose_ns
        return t_ns - last > self._timeout_ns

    def estimating(self, t_ns: int) -> None:
        """Note that the observer gives an estimate at `t_ns` (the settling starts)."""
        if self._estimating_since_ns is None:
            self._estimating_since_ns = t_ns

    def settle_again(self) -> None:
        """Make a first decision wait for the filter to settle anew (after a pose loss)."""
        self._estimating_since_ns = None

    def settled(self, t_ns: int) -> bool:
        """Return whether the filter has given estimates for the settling time."""
        since = self._estimating_since_ns
        return since is not None and t_ns - since >= self._settle_ns

    def new_breach(self) -> ConsistencyBreach | None:
        """Return the observer's noise-model breach the first time it is seen, else None."""
        if self._breached:
            return None
        breach = self.observer.breach()
        self._breached = breach is not None
        return breach

    def _reject(self, t_ns: int, what: str) -> None:
        self._stats.rejected_samples += 1
        # Log the first few and then every 100th, so a flood cannot swamp the log.
        n = self._stats.rejected_samples
        if n <= 5 or n % 100 == 0:
            self._event(
                t_ns, EventLevel.WARN, EventCode.SAMPLE_REJECTED,
                f"observer rejected {what} ({n} so far)",
            )  # fmt: skip
