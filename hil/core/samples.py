"""Timestamped samples that cross the adapter boundary, with units and frames.

Times are integer nanoseconds (`t_ns`) on the run's clock; lengths in metres,
angles in radians, velocities in m/s and rad/s. Every pose carries its frame so
that a lab NED pose cannot be mistaken for an arena pose. Obstacle rectangles are
:class:`hil.core.shapes.Rect`, the shape scenarios use too.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from hil.core.arrays import FloatArray
from hil.core.shapes import Rect


class Frame(enum.Enum):
    """Coordinate frames a sample can be expressed in."""

    ARENA = "arena"
    """The paper's planar arena frame: x, y in metres, heading psi about z down."""
    LAB_NED = "world_ned"
    """The lab's motion-capture world frame (north, east, down)."""
    BODY = "body"
    """The vessel's body frame: x forward, y starboard, z down (Fossen)."""


class SampleError(ValueError):
    """A sample that cannot be used: non-finite, out of range or in the wrong frame."""


def _require_finite(name: str, *values: float) -> None:
    if not all(math.isfinite(v) for v in values):
        raise SampleError(f"{name} has non-finite values: {values!r}")


@dataclass(frozen=True, slots=True)
class PoseSample:
    """A planar pose measurement (Qualisys motion capture).

    Attributes:
        t_ns: Time the pose was measured (ns on the run clock).
        x_m: Position x (m).
        y_m: Position y (m).
        yaw_rad: Heading (rad).
        frame: Frame of the position and heading.
    """

    t_ns: int
    x_m: float
    y_m: float
    yaw_rad: float
    frame: Frame = Frame.ARENA

    def __post_init__(self) -> None:
        _require_finite("pose", self.x_m, self.y_m, self.yaw_rad)

    def eta(self, frame: Frame = Frame.ARENA) -> FloatArray:
        """Return (x, y, psi), shape (3,), refusing a frame other than the sample's own."""
        if frame is not self.frame:
            raise SampleError(f"pose is in frame {self.frame.value!r}, not {frame.value!r}")
        return np.array([self.x_m, self.y_m, self.yaw_rad])


@dataclass(frozen=True, slots=True)
class ImuSample:
    """An IMU measurement in the body frame.

    Attributes:
        t_ns: Time of the measurement (ns on the run clock).
        accel_x_mps2: Specific force along body x (m/s^2).
        accel_y_mps2: Specific force along body y (m/s^2).
        yaw_rate_radps: Angular rate about body z (rad/s).
    """

    t_ns: int
    accel_x_mps2: float
    accel_y_mps2: float
    yaw_rate_radps: float

    def __post_init__(self) -> None:
        _require_finite("imu", self.accel_x_mps2, self.accel_y_mps2, self.yaw_rate_radps)

    def as_array(self) -> FloatArray:
        """Return (ax, ay, r), shape (3,)."""
        return np.array([self.accel_x_mps2, self.accel_y_mps2, self.yaw_rate_radps])


@dataclass(frozen=True, slots=True)
class VelocityReference:
    """A body-velocity reference nu_ref = (u, v, r) for the low-level loop.

    Attributes:
        t_ns: Time the reference was issued (ns).
        surge_mps: u (m/s).
        sway_mps: v (m/s).
        yaw_rate_radps: r (rad/s).
    """

    t_ns: int
    surge_mps: float
    sway_mps: float
    yaw_rate_radps: float

    def __post_init__(self) -> None:
        _require_finite("velocity reference", self.surge_mps, self.sway_mps, self.yaw_rate_radps)

    def as_array(self) -> FloatArray:
        """Return (u, v, r), shape (3,)."""
        return np.array([self.surge_mps, self.sway_mps, self.yaw_rate_radps])


@dataclass(frozen=True, slots=True)
class ThrusterCommand:
    """Normalized thruster commands and azimuth angles sent to the vessel.

    Attributes:
        t_ns: Time the command was issued (ns).
        tunnel: Bow tunnel thruster command in [-1, 1] (saturates at 0.7).
        port: Port azimuth thrust command in [-1, 1].
        starboard: Starboard azimuth thrust command in [-1, 1].
        port_angle_rad: Port azimuth angle (rad, body frame, 0 = thrust forward).
        starboard_angle_rad: Starboard azimuth angle (rad).
    """

    t_ns: int
    tunnel: float
    port: float
    starboard: float
    port_angle_rad: float
    starboard_angle_rad: float

    def __post_init__(self) -> None:
        values = (self.tunnel, self.port, self.starboard)
        _require_finite("thruster command", *values, self.port_angle_rad, self.starboard_angle_rad)
        if any(abs(v) > 1.0 for v in values):
            raise SampleError(f"thruster command outside [-1, 1]: {values!r}")

    @staticmethod
    def zero(t_ns: int) -> ThrusterCommand:
        """Return the all-stop command at `t_ns`, azimuths at their reference angles."""
        return ThrusterCommand(t_ns, 0.0, 0.0, 0.0, math.pi / 2, -math.pi / 2)


def obstacle_rect(x_min_m: float, x_max_m: float, y_min_m: float, y_max_m: float) -> Rect:
    """Return the obstacle rectangle with these bounds (m), refusing what a layout refuses.

    Raises:
        SampleError: A bound is not finite or the rectangle has no area.
    """
    rect = Rect(x_min_m, x_max_m, y_min_m, y_max_m)
    _require_obstacle(rect)
    return rect


def _require_obstacle(rect: Rect) -> None:
    _require_finite("rectangle", rect.x_min_m, rect.x_max_m, rect.y_min_m, rect.y_max_m)
    if not (rect.x_min_m < rect.x_max_m and rect.y_min_m < rect.y_max_m):
        raise SampleError(f"rectangle has empty extent: {rect!r}")


@dataclass(frozen=True, slots=True)
class ObstacleLayout:
    """The real (not inflated) obstacles known at a time.

    Attributes:
        t_ns: Time the layout was observed (ns).
        obstacles: The obstacles as arena-frame rectangles, each finite with area.
    """

    t_ns: int
    obstacles: tuple[Rect, ...]

    def __post_init__(self) -> None:
        for rect in self.obstacles:
            _require_obstacle(rect)
