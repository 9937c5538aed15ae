"""Telling the crew why the vessel's feeds are refused: lines, the run's events, the summary.

:class:`FeedWatch` reads the ROS backend's counters (:class:`hil.adapters.feed_health.
FeedHealth`) and reports each new reason a topic's messages are refused at once, as a
progress line and a ``sample_rejected`` event in the run's log; a count that grew is
logged again at most once per `period_s`, so a flood cannot swamp the log.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from hil.adapters.feed_health import FeedHealth, RejectReason
from hil.adapters.ros import RosWorld
from hil.core.records import EventLevel
from hil.runtime.events import EventCode
from hil.runtime.protocols import RunLog

__all__ = ["FeedWatch"]


class FeedWatch:
    """Reports the refusals of the pose and IMU topics as they appear.

    Args:
        ros: The open ROS backend.
        log: Where the events go (the run's recorder).
        progress: Receives one line per new reason (the command prints it).
        period_s: Least wall time between two events of one topic and reason (s).
    """

    def __init__(self, ros: RosWorld, log: RunLog, progress: Callable[[str], None],
                 period_s: float = 5.0) -> None:
        self._ros = ros
        self._log = log
        self._progress = progress
        self._period_s = period_s
        # (topic, reason) -> (count logged, monotonic time logged (s)).
        self._reported: dict[tuple[str, RejectReason], tuple[int, float]] = {}

    def healths(self) -> tuple[FeedHealth, FeedHealth]:
        """Return the pose and IMU topics' counters now."""
        return self._ros.pose_health(), self._ros.imu_health()

    def poll(self) -> None:
        """Log an event per new reason or grown count (once per period); a line per new reason.

        Not called after the loop ends: the run's last events are the loop's (stopped,
        at rest); the summary carries the final counts.
        """
        assert self._ros.clock is not None
        t_ns = max(0, self._ros.clock.now_ns())
        now_s = time.monotonic()
        for health in self.healths():
            for rejection in health.rejections:
                key = (health.topic, rejection.reason)
                before = self._reported.get(key)
                if before is not None and (before[0] == rejection.count
                                           or now_s - before[1] < self._period_s):
                    continue
                self._reported[key] = (rejection.count, now_s)
                text = f"{health.noun} on {health.topic} refused: {rejection.text()}"
                self._log.event(t_ns, EventLevel.WARN, EventCode.SAMPLE_REJECTED.value, text)
                if before is None:
                    self._progress(text)

    def status(self) -> str:
        """Return the refusals for the status line ("" when none), e.g. ``pose: 3 stale``."""
        parts: list[str] = []
        for health, short in zip(self.healths(), ("pose", "IMU"), strict=True):
            parts.extend(f"{short} {r.text()}" for r in health.rejections)
        return "; refused " + "; ".join(parts) if parts else ""

    def waiting(self, topic: str) -> str:
        """Return why no pose was taken yet: what the topic delivered and who publishes."""
        health = self._ros.pose_health()
        said = health.describe()
        if health.received == 0 and not health.rejections:
            publishers = self._ros.publishers_on(topic)
            said += (f" ({publishers} publisher(s) seen: are their stamps and types right?)"
                     if publishers else
                     f" and no publisher seen: is the motion capture publishing? "
                     f"(ros2 topic echo {topic})")
        return said

    def summary(self) -> tuple[str, ...]:
        """Return, per topic with refusals, what it delivered and refused (for the summary)."""
        return tuple(f"{h.topic}: {h.describe()}" for h in self.healths() if h.rejections)
