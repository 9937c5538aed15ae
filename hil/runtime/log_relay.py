"""A run log that passes every record on to another: the base of the logs around a run's.

A live view, a spinner or a telemetry tee sees every record the runtime makes and keeps
none of them: it subclasses :class:`RunLogRelay` and overrides only the records it
reads, calling the relay's method (or ``self.inner``) so that the run's own log still
gets each one first.
"""

from __future__ import annotations

from hil.core.arrays import FloatArray
from hil.core.records import ControllerReady, Decision, EventLevel
from hil.core.samples import ImuSample, ObstacleLayout, PoseSample, ThrusterCommand
from hil.runtime.protocols import RunLog

__all__ = ["RunLogRelay"]


class RunLogRelay:
    """A :class:`~hil.runtime.protocols.RunLog` that passes every record to `inner`.

    Args:
        inner: The log that keeps the records (the recorder, or another relay).
    """

    def __init__(self, inner: RunLog) -> None:
        self.inner = inner

    def pose(self, sample: PoseSample) -> None:
        """Pass a pose sample on."""
        self.inner.pose(sample)

    def imu(self, sample: ImuSample) -> None:
        """Pass an IMU sample on."""
        self.inner.imu(sample)

    def estimate(self, t_ns: int, eta: FloatArray, nu: FloatArray) -> None:
        """Pass the observer's estimate on (eta (3,), nu (3,))."""
        self.inner.estimate(t_ns, eta, nu)

    def velocity_reference(self, t_ns: int, nu_ref: FloatArray) -> None:
        """Pass the velocity reference sent to the low level on, (3,)."""
        self.inner.velocity_reference(t_ns, nu_ref)

    def force(self, t_ns: int, tau: FloatArray) -> None:
        """Pass the generalized force demanded on, (3,)."""
        self.inner.force(t_ns, tau)

    def thrusters(self, command: ThrusterCommand) -> None:
        """Pass a thruster command on."""
        self.inner.thrusters(command)

    def decision(self, record: Decision) -> None:
        """Pass a decision on."""
        self.inner.decision(record)

    def obstacles(self, layout: ObstacleLayout) -> None:
        """Pass an obstacle layout on."""
        self.inner.obstacles(layout)

    def event(self, t_ns: int, level: EventLevel, code: str, text: str) -> None:
        """Pass an event on."""
        self.inner.event(t_ns, level, code, text)

    def controller_ready(self, record: ControllerReady) -> None:
        """Pass a controller taken on."""
        self.inner.controller_ready(record)
