"""The transform from the lab's motion-capture frames to the arena frame.

The lab's world is NED (x north, y east, z down) and the mocap rigid body is
FRD; the paper's arena is a planar frame with z down as well, so both share the
handedness of the heading. The arena is the lab world rotated by `yaw_rad` about
z and shifted to `origin`; the vessel's body origin sits at `body_offset` in the
mocap rigid body's frame, rotated by `body_yaw_rad`.

The adapters map each received pose with it; the recorder maps hil's arena poses
back to the lab's frame for the lab's topic and stores it on ``/tf_static``; replay
maps recorded lab poses (N, 3) in bulk (:meth:`ArenaTransform.poses_to_arena`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hil.core.arrays import FloatArray
from hil.core.geometry import wrap_angle, wrap_angles
from hil.core.samples import Frame, PoseSample, SampleError


@dataclass(frozen=True, slots=True)
class ArenaTransform:
    """Where the arena lies in the lab's NED world, and the vessel in the mocap body.

    Attributes:
        origin_north_m: Arena origin's north coordinate in the lab frame (m).
        origin_east_m: Arena origin's east coordinate in the lab frame (m).
        yaw_rad: Rotation of the arena's x axis from north, about down (rad).
        body_offset_x_m: Vessel body origin in the mocap body frame, forward (m).
        body_offset_y_m: Vessel body origin in the mocap body frame, starboard (m).
        body_yaw_rad: Heading of the vessel body relative to the mocap body (rad).
    """

    origin_north_m: float = 0.0
    origin_east_m: float = 0.0
    yaw_rad: float = 0.0
    body_offset_x_m: float = 0.0
    body_offset_y_m: float = 0.0
    body_yaw_rad: float = 0.0

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            if not math.isfinite(getattr(self, name)):
                raise SampleError(f"arena transform field {name!r} is not finite")

    def point_to_arena(self, north_m: float, east_m: float) -> tuple[float, float]:
        """Map a point of the lab's NED world to arena (x, y) (m); no body offset."""
        dn, de = north_m - self.origin_north_m, east_m - self.origin_east_m
        ca, sa = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        return ca * dn + sa * de, -sa * dn + ca * de

    def point_to_lab(self, x_m: float, y_m: float) -> tuple[float, float]:
        """Map an arena point (x, y) to the lab's (north, east) (m); inverse of the above."""
        ca, sa = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        return self.origin_north_m + ca * x_m - sa * y_m, self.origin_east_m + sa * x_m + ca * y_m

    def to_arena(self, pose: PoseSample) -> PoseSample:
        """Map a mocap pose in the lab's NED frame to the vessel's pose in the arena."""
        if pose.frame is Frame.ARENA:
            return pose
        if pose.frame is not Frame.LAB_NED:
            raise SampleError(f"cannot map a pose in frame {pose.frame.value!r} to the arena")
        c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
        north = pose.x_m + c * self.body_offset_x_m - s * self.body_offset_y_m
        east = pose.y_m + s * self.body_offset_x_m + c * self.body_offset_y_m
        x_m, y_m = self.point_to_arena(north, east)
        return PoseSample(
            t_ns=pose.t_ns,
            x_m=x_m,
            y_m=y_m,
            yaw_rad=wrap_angle(pose.yaw_rad + self.body_yaw_rad - self.yaw_rad),
            frame=Frame.ARENA,
        )

    def to_lab(self, pose: PoseSample) -> PoseSample:
        """Map a vessel pose in the arena to the mocap body's pose in the lab (inverse)."""
        if pose.frame is not Frame.ARENA:
            raise SampleError(f"expected an arena pose, got frame {pose.frame.value!r}")
        north, east = self.point_to_lab(pose.x_m, pose.y_m)
        yaw = wrap_angle(pose.yaw_rad + self.yaw_rad - self.body_yaw_rad)
        c, s = math.cos(yaw), math.sin(yaw)
        return PoseSample(
            t_ns=pose.t_ns,
            x_m=north - (c * self.body_offset_x_m - s * self.body_offset_y_m),
            y_m=east - (s * self.body_offset_x_m + c * self.body_offset_y_m),
            yaw_rad=yaw,
            frame=Frame.LAB_NED,
        )

    def poses_to_arena(self, lab: FloatArray) -> FloatArray:
        """Map mocap poses (N, 3) (north m, east m, yaw rad) to vessel poses (N, 3) in the arena.

        The vectorized :meth:`to_arena`, the same arithmetic.
        """
        yaw = lab[:, 2]
        c, s = np.cos(yaw), np.sin(yaw)
        north = lab[:, 0] + c * self.body_offset_x_m - s * self.body_offset_y_m
        east = lab[:, 1] + s * self.body_offset_x_m + c * self.body_offset_y_m
        dn, de = north - self.origin_north_m, east - self.origin_east_m
        ca, sa = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        psi = wrap_angles(yaw + self.body_yaw_rad - self.yaw_rad)
        return np.column_stack([ca * dn + sa * de, -sa * dn + ca * de, psi])

    def poses_to_lab(self, arena: FloatArray) -> FloatArray:
        """Map vessel poses (N, 3) (x m, y m, psi rad) in the arena to mocap poses (N, 3).

        The vectorized :meth:`to_lab`, the same arithmetic.
        """
        ca, sa = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        north = self.origin_north_m + ca * arena[:, 0] - sa * arena[:, 1]
        east = self.origin_east_m + sa * arena[:, 0] + ca * arena[:, 1]
        yaw = wrap_angles(arena[:, 2] + self.yaw_rad - self.body_yaw_rad)
        c, s = np.cos(yaw), np.sin(yaw)
        return np.column_stack([
            north - (c * self.body_offset_x_m - s * self.body_offset_y_m),
            east - (s * self.body_offset_x_m + c * self.body_offset_y_m),
            yaw,
        ])  # fmt: skip
