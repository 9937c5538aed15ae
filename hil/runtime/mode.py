"""What the control loop is doing: one mode at a time, each with its defined behaviour."""

from __future__ import annotations

import enum

__all__ = ["Mode"]


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
