"""The lab-to-arena transform (re-exported) and the ROS adapter's quaternion helpers.

:class:`ArenaTransform` lives in :mod:`hil.core.arena_frame` (the recorder uses it too).

The lab's world is NED (x north, y east, z down) and the mocap rigid body is
FRD; the paper's arena is a planar frame with z down as well, so both share the
handedness of the heading. The arena is the lab world rotated by `yaw_rad` about
z and shifted to `origin`; the vessel's body origin sits at `body_offset` in the
mocap rigid body's frame, rotated by `body_yaw_rad`.
"""

from __future__ import annotations

import math

from hil.core.arena_frame import ArenaTransform
from hil.core.geometry import quaternion_yaw, yaw_quaternion
from hil.core.samples import SampleError

__all__ = ["ArenaTransform", "quaternion_from_yaw", "yaw_from_quaternion"]


def yaw_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """Return the yaw (rad, in [-pi, pi)) of a unit quaternion given in ROS order (x, y, z, w).

    Raises:
        SampleError: If the quaternion is not finite or far from unit length.
    """
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(norm) or abs(norm - 1.0) > 1e-3:
        raise SampleError(f"quaternion is not a unit quaternion: {(x, y, z, w)!r}")
    return quaternion_yaw(x, y, z, w)


def quaternion_from_yaw(yaw_rad: float) -> tuple[float, float, float, float]:
    """Return the unit quaternion (x, y, z, w) of a pure rotation by `yaw_rad` about z."""
    return yaw_quaternion(yaw_rad)
