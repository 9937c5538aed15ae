"""What the stack reads from and writes to the world, as `typing.Protocol`s.

The stack never knows which world it runs in: a simulated vessel, a recorded log
or the real vessel over ROS 2 all provide these five interfaces (DESIGN.md).
Sources are polled: `poll()` returns the samples that arrived since the last
call, oldest first, each stamped with its measurement time on the run clock.
"""

from __future__ import annotations

from typing import Protocol

from hil.core.samples import ImuSample, ObstacleLayout, PoseSample, ThrusterCommand


class Clock(Protocol):
    """The run's clock: wall time on the vessel, simulated time in sim and replay."""

    def now_ns(self) -> int:
        """Return the current time (ns)."""

    def sleep_until(self, t_ns: int) -> None:
        """Block until `t_ns`; a simulated clock advances the world to it instead."""


class PoseSource(Protocol):
    """The motion-capture pose feed (Qualisys), already in the arena frame."""

    def poll(self) -> list[PoseSample]:
        """Return the pose samples received since the last call, oldest first."""


class ImuSource(Protocol):
    """The IMU feed in the body frame."""

    def poll(self) -> list[ImuSample]:
        """Return the IMU samples received since the last call, oldest first."""


class ObstacleSource(Protocol):
    """Obstacle positions, static or moving."""

    def latest(self) -> ObstacleLayout:
        """Return the newest known layout (its `t_ns` tells when it last changed)."""


class ThrusterSink(Protocol):
    """Where thruster commands go."""

    def send(self, command: ThrusterCommand) -> None:
        """Send one command; raise `ThrusterSinkError` if it cannot be delivered."""


class ThrusterSinkError(RuntimeError):
    """A thruster command could not be delivered (link down, driver error)."""
