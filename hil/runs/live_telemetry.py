"""``hil vessel``'s live telemetry: the run's log, teed to ROS 2 topics while it runs.

:class:`TelemetryLog` is a :class:`~hil.runtime.protocols.RunLog` that forwards every
record to the run's log first (the recorder: the live view never costs recorded data)
and queues each decision and event for :class:`hil.adapters.ros_telemetry.RosTelemetry`,
which publishes them (and ``/diagnostics``, :mod:`hil.runs.live_diagnostics`) from its
own thread. A failing publish is recorded as a ``telemetry_failed`` event in the log.
"""

from __future__ import annotations

from collections.abc import Callable

from hil.adapters.ros_telemetry import RosTelemetry
from hil.core.records import Decision, Event, EventLevel
from hil.runs.live_diagnostics import FeedView, VesselDiagnostics
from hil.runtime.events import EventCode
from hil.runtime.log_relay import RunLogRelay
from hil.runtime.loop import Runtime
from hil.runtime.protocols import RunLog

__all__ = ["TelemetryLog"]


class TelemetryLog(RunLogRelay):
    """A RunLog that records into `inner` and publishes decisions and events live.

    Args:
        inner: The run's log (the recorder, or a live Rerun view around it).
        node: The ROS world's open node; the publishers are created on it.
        now_ns: The node clock (ns).

    Raises:
        ImportError: The telemetry's message packages are missing.
    """

    def __init__(self, inner: RunLog, node: object, now_ns: Callable[[], int]) -> None:
        super().__init__(inner)
        self._now_ns = now_ns
        self.telemetry = RosTelemetry(node, now_ns, self._failed)
        self.last_decision: Decision | None = None
        """The newest decision taken (for the diagnostics)."""

    def _failed(self, text: str) -> None:
        # Into the recorder only: publishing this event would fail the same way.
        self.inner.event(max(0, self._now_ns()), EventLevel.WARN,
                         EventCode.TELEMETRY_FAILED.value, text)

    def watch(self, runtime: Runtime, feeds: FeedView, node_name: str) -> None:
        """Start publishing, with ``/diagnostics`` on `runtime` and `feeds`."""
        self.telemetry.start(VesselDiagnostics(runtime, feeds, lambda: self.last_decision,
                                               node_name))

    def close(self) -> None:
        """Publish what is queued and stop publishing."""
        self.telemetry.close()

    def decision(self, record: Decision) -> None:
        """Record one decision, then queue it for the live topic."""
        self.inner.decision(record)
        self.last_decision = record
        self.telemetry.decision(record)

    def event(self, t_ns: int, level: EventLevel, code: str, text: str) -> None:
        """Record an event, then queue it for the live topic."""
        self.inner.event(t_ns, level, code, text)
        self.telemetry.event(Event(t_ns, level, code, text))

