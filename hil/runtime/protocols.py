"""The components of the stack as the runtime sees them (typing.Protocol).

The runtime composes an observer, a symbolic decision source, a velocity
controller and a thrust allocator; these protocols are the narrow waists it
calls, so a component can be replaced (another allocator, a replayed
controller) without touching the loop.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from hil.controllers.consistency import ConsistencyBreach
from hil.controllers.symbolic import Answer, Select
from hil.core.arrays import FloatArray, IntArray
from hil.core.records import ControllerReady, ControllerSource, Decision, EventLevel
from hil.core.samples import ImuSample, ObstacleLayout, PoseSample, ThrusterCommand


class Observer(Protocol):
    """A state observer fed with timestamped samples."""

    def update_pose(self, sample: PoseSample) -> bool:
        """Fuse a pose; return False if it was rejected (stale, gated, non-finite)."""

    def update_imu(self, sample: ImuSample) -> bool:
        """Fuse an IMU sample; return False if it was rejected."""

    def estimate(self) -> tuple[FloatArray, FloatArray] | None:
        """Return the newest (eta (3,), nu (3,)), or None before the filter has started."""

    def breach(self) -> ConsistencyBreach | None:
        """Return the first breach of the estimation premise so far; None: none, or not watched.

        See :mod:`hil.controllers.consistency`.
        """


class SymbolicController(Protocol):
    """A synthesized controller over (cell, reference in force): values and safe inputs."""

    def locate(self, state: FloatArray) -> int:
        """Return the flat cell index of `state` (x, y, psi), -1 outside the grid."""

    def nearest_input(self, velocity: FloatArray) -> int:
        """Return the input-grid index nearest a body velocity (u, v, r)."""

    def value(self, state: FloatArray, reference: int, first: bool) -> float:
        """Return the value (steps to target) at `state` with input `reference` in force.

        +inf when no input is safe there (`first`: the run's first command).
        """

    def safe_input_indices(self, state: FloatArray, reference: int, first: bool) -> IntArray:
        """Return the input-grid indices of every safe input at `state`, shape (k,)."""

    def decide(
        self,
        state: FloatArray,
        reference: int,
        first: bool,
        previous: FloatArray,
        select: Select,
        wait_select: Select,
    ) -> Answer:
        """Take the decision at `state` with `reference` in force, the cell located once.

        Returns cell, value, the inputs listed, the one `select` chooses (`wait_select`
        where docking is not winning but the vessel can stay safe) and its contract
        (:meth:`hil.controllers.symbolic.SymbolicAdapter.decide`); the runtime monitor
        judges every tick's estimate with the contract.
        """

    @property
    def inputs(self) -> FloatArray:
        """The input grid, shape (n_inputs, 3), rows (u, v, r)."""

    @property
    def source(self) -> ControllerSource:
        """Where this controller came from (solved, the store, memory)."""


class LowLevel(Protocol):
    """Velocity controller and thrust allocation, run together once per loop tick.

    They form one step because the controller's anti-windup needs the force the
    allocator could actually achieve.
    """

    def step(self, nu_ref: FloatArray, nu_hat: FloatArray, t_ns: int) -> LowLevelOutput:
        """Return the force demand and the thruster command for this tick."""

    def reset(self) -> None:
        """Forget integrator state (after a hold or a stop)."""


@dataclass(frozen=True, slots=True)
class LowLevelOutput:
    """One tick of the low level.

    Attributes:
        tau: Force demanded by the velocity controller (X N, Y N, N N m), shape (3,).
        command: Thruster commands that realize it as closely as the limits allow.
    """

    tau: FloatArray
    command: ThrusterCommand


class RunLog(Protocol):
    """Where the runtime records every message in and out, and every decision.

    The bag recorder implements it for real runs; :class:`hil.runtime.trace.MemoryLog`
    keeps everything in memory (campaigns, tests).
    """

    def pose(self, sample: PoseSample) -> None:
        """Record a pose sample as received."""

    def imu(self, sample: ImuSample) -> None:
        """Record an IMU sample as received."""

    def estimate(self, t_ns: int, eta: FloatArray, nu: FloatArray) -> None:
        """Record the observer's estimate (eta (3,), nu (3,))."""

    def velocity_reference(self, t_ns: int, nu_ref: FloatArray) -> None:
        """Record the velocity reference sent to the low level, (3,)."""

    def force(self, t_ns: int, tau: FloatArray) -> None:
        """Record the generalized force demanded by the velocity controller, (3,)."""

    def thrusters(self, command: ThrusterCommand) -> None:
        """Record a thruster command as sent."""

    def decision(self, record: Decision) -> None:
        """Record one decision of the symbolic controller."""

    def obstacles(self, layout: ObstacleLayout) -> None:
        """Record an obstacle layout when it changes."""

    def event(self, t_ns: int, level: EventLevel, code: str, text: str) -> None:
        """Record a runtime event or fault."""

    def controller_ready(self, record: ControllerReady) -> None:
        """Record a controller taken from the re-synthesis (version, solve time, source)."""
