"""An in-memory run log: everything the runtime records, kept as Python lists.

It implements :class:`hil.runtime.protocols.RunLog` for runs that need no bag
(Monte Carlo campaigns, tests) and is the reference the bag recorder's round
trip is compared with.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hil.core.arrays import FloatArray
from hil.core.records import ControllerReady, Decision, EventLevel
from hil.core.samples import ImuSample, ObstacleLayout, PoseSample, ThrusterCommand


@dataclass
class MemoryLog:
    """Every recorded item, in arrival order, one list per stream."""

    poses: list[PoseSample] = field(default_factory=list)
    imus: list[ImuSample] = field(default_factory=list)
    estimates: list[tuple[int, FloatArray, FloatArray]] = field(default_factory=list)
    velocity_references: list[tuple[int, FloatArray]] = field(default_factory=list)
    forces: list[tuple[int, FloatArray]] = field(default_factory=list)
    thruster_commands: list[ThrusterCommand] = field(default_factory=list)
    decisions: list[Decision] = field(default_factory=list)
    layouts: list[ObstacleLayout] = field(default_factory=list)
    events: list[tuple[int, EventLevel, str, str]] = field(default_factory=list)
    controllers: list[ControllerReady] = field(default_factory=list)

    def pose(self, sample: PoseSample) -> None:
        """Record a pose sample."""
        self.poses.append(sample)

    def imu(self, sample: ImuSample) -> None:
        """Record an IMU sample."""
        self.imus.append(sample)

    def estimate(self, t_ns: int, eta: FloatArray, nu: FloatArray) -> None:
        """Record a state estimate (eta (3,), nu (3,))."""
        self.estimates.append((t_ns, eta.copy(), nu.copy()))

    def velocity_reference(self, t_ns: int, nu_ref: FloatArray) -> None:
        """Record a velocity reference (3,)."""
        self.velocity_references.append((t_ns, nu_ref.copy()))

    def force(self, t_ns: int, tau: FloatArray) -> None:
        """Record a generalized force (3,)."""
        self.forces.append((t_ns, np.asarray(tau, dtype=np.float64).copy()))

    def thrusters(self, command: ThrusterCommand) -> None:
        """Record a thruster command."""
        self.thruster_commands.append(command)

    def decision(self, record: Decision) -> None:
        """Record a decision."""
        self.decisions.append(record)

    def obstacles(self, layout: ObstacleLayout) -> None:
        """Record an obstacle layout."""
        self.layouts.append(layout)

    def event(self, t_ns: int, level: EventLevel, code: str, text: str) -> None:
        """Record an event."""
        self.events.append((t_ns, level, code, text))

    def controller_ready(self, record: ControllerReady) -> None:
        """Record a controller taken from the re-synthesis."""
        self.controllers.append(record)

    def event_codes(self) -> list[str]:
        """Return the codes of all events, in order."""
        return [code for _, _, code, _ in self.events]
