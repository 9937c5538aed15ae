"""The lab's azimuth wrench convention, in one place: encode and the one decode rule.

The lab's driver takes each azimuth thruster's command as a geometry_msgs/Wrench whose
force is the normalized thrust as a vector in the body frame:
``(force.x, force.y) = c (cos a, sin a)``, c in [-1, 1] the propeller command and a the
pod's angle (rad). The vector fixes the direction of the thrust, not the sign of the
propeller (c at a and -c at a + pi give the same vector), so decoding needs a rule.
The rule, everywhere hil reads such a vector (the ROS sim vessel, lab bags): like a
driver that turns each pod at most 90 degrees, the pod keeps the side of its previous
angle and reverses the propeller when the vector points behind it; a zero vector
carries no angle and keeps the previous one; the magnitude is clipped to 1.
"""

from __future__ import annotations

import math

import numpy as np

from hil.core.arrays import FloatArray
from hil.core.geometry import wrap_angle

__all__ = ["azimuth_command", "azimuth_commands", "azimuth_vector", "azimuth_vectors"]

ZERO_VECTOR = 1e-12
"""A thrust vector shorter than this carries no angle."""


def azimuth_vector(thrust: float, angle_rad: float) -> tuple[float, float]:
    """Return the Wrench force (x, y) of propeller command `thrust` at pod angle `angle_rad`."""
    return thrust * math.cos(angle_rad), thrust * math.sin(angle_rad)


def azimuth_vectors(thrust: FloatArray, angle_rad: FloatArray) -> FloatArray:
    """Return :func:`azimuth_vector` for commands (N,) and angles (N,): forces, shape (N, 2)."""
    t = np.asarray(thrust, dtype=np.float64)
    a = np.asarray(angle_rad, dtype=np.float64)
    out: FloatArray = np.column_stack([t * np.cos(a), t * np.sin(a)])
    return out


def azimuth_command(fx: float, fy: float, previous_angle_rad: float) -> tuple[float, float]:
    """Return (propeller command in [-1, 1], pod angle rad) for a Wrench force (fx, fy).

    The decode rule of this module: the pod keeps the side of `previous_angle_rad`.
    """
    magnitude = math.hypot(fx, fy)
    if magnitude < ZERO_VECTOR:
        return 0.0, previous_angle_rad
    angle = math.atan2(fy, fx)
    if math.cos(angle - previous_angle_rad) < 0.0:
        return -min(magnitude, 1.0), wrap_angle(angle + math.pi)
    return min(magnitude, 1.0), angle


def azimuth_commands(
    fx: FloatArray, fy: FloatArray, first_angle_rad: float
) -> tuple[FloatArray, FloatArray]:
    """Decode a stream of Wrench forces (N,), (N,) in time order by :func:`azimuth_command`.

    Each row keeps the side of the angle decoded for the row before it;
    `first_angle_rad` stands before the first (the pod's reference angle).

    Returns:
        Propeller commands (N,) in [-1, 1] and pod angles (N,) (rad).
    """
    n = len(fx)
    thrust = np.zeros(n)
    angle = np.zeros(n)
    previous = first_angle_rad
    for k in range(n):
        thrust[k], previous = azimuth_command(float(fx[k]), float(fy[k]), previous)
        angle[k] = previous
    return thrust, angle
