"""Angles and planar rotations, in one place (like Fossen's `ssa()`).

Headings are radians wrapped to [-pi, pi). The body frame is x forward, y
starboard; the world frame's z points down, so R(psi) below maps body to world.
"""

from __future__ import annotations

import math

import numpy as np

from hil.core.arrays import FloatArray
from hil.core.jit import njit

TWO_PI = 2.0 * math.pi


@njit
def wrap_angle(angle_rad: float) -> float:
    """Wrap an angle to [-pi, pi).

    Args:
        angle_rad: Any finite angle (rad).

    Returns:
        The same direction in [-pi, pi) (rad).
    """
    wrapped = (angle_rad + math.pi) % TWO_PI - math.pi
    # Floating-point modulo can return exactly pi for inputs just below -pi.
    if wrapped >= math.pi:
        wrapped -= TWO_PI
    return wrapped


def wrap_angles(angles_rad: FloatArray) -> FloatArray:
    """Wrap an array of angles to [-pi, pi), elementwise (any shape, rad)."""
    wrapped = np.mod(np.asarray(angles_rad, dtype=np.float64) + np.pi, TWO_PI) - np.pi
    return np.where(wrapped >= np.pi, wrapped - TWO_PI, wrapped)


@njit
def rotation(psi_rad: float) -> FloatArray:
    """Return R(psi), the (3, 3) rotation from body (u, v, r) to world (x, y, psi) rates."""
    c = math.cos(psi_rad)
    s = math.sin(psi_rad)
    out = np.zeros((3, 3))
    out[0, 0] = c
    out[0, 1] = -s
    out[1, 0] = s
    out[1, 1] = c
    out[2, 2] = 1.0
    return out


@njit
def body_to_world(psi_rad: float, nu: FloatArray) -> FloatArray:
    """Return eta_dot = R(psi) nu, shape (3,), for body velocities nu = (u, v, r)."""
    c = math.cos(psi_rad)
    s = math.sin(psi_rad)
    out = np.empty(3)
    out[0] = c * nu[0] - s * nu[1]
    out[1] = s * nu[0] + c * nu[1]
    out[2] = nu[2]
    return out


# ---- yaw and unit quaternions (ROS order x, y, z, w): the one convention ----


def quaternion_yaw(x: float, y: float, z: float, w: float) -> float:
    """Return the yaw (rad, wrapped to [-pi, pi)) of a unit quaternion in ROS order.

    The rotation about z of any attitude: atan2(2 (w z + x y), 1 - 2 (y^2 + z^2)).
    """
    return wrap_angle(math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


def quaternion_yaws(x: FloatArray, y: FloatArray, z: FloatArray, w: FloatArray) -> FloatArray:
    """Return :func:`quaternion_yaw` elementwise: components of one shape, yaws (rad) alike."""
    return wrap_angles(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


def yaw_quaternion(yaw_rad: float) -> tuple[float, float, float, float]:
    """Return the unit quaternion (x, y, z, w) of a pure rotation by `yaw_rad` about z."""
    half = 0.5 * yaw_rad
    return (0.0, 0.0, math.sin(half), math.cos(half))


def yaw_quaternions(yaw_rad: FloatArray) -> FloatArray:
    """Return :func:`yaw_quaternion` for yaws (N,) (rad): quaternions (x, y, z, w), shape (N, 4)."""
    half = 0.5 * np.asarray(yaw_rad, dtype=np.float64).reshape(-1)
    zeros = np.zeros(half.shape[0])
    out: FloatArray = np.column_stack([zeros, zeros, np.sin(half), np.cos(half)])
    return out
