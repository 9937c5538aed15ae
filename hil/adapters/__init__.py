"""Adapters: interfaces (typing.Protocol) and backends (sim, log, ros) for the world.

Backends are modules of their own (`hil.adapters.sim`, `hil.adapters.log`,
`hil.adapters.ros`) so that importing the interfaces pulls in neither numba nor
rclpy.
"""

from hil.adapters.frames import ArenaTransform, quaternion_from_yaw, yaw_from_quaternion
from hil.adapters.interfaces import (
    Clock,
    ImuSource,
    ObstacleSource,
    PoseSource,
    ThrusterSink,
    ThrusterSinkError,
)
from hil.core.samples import (
    Frame,
    ImuSample,
    ObstacleLayout,
    PoseSample,
    SampleError,
    ThrusterCommand,
    VelocityReference,
)
from hil.core.shapes import Rect

__all__ = [
    "ArenaTransform",
    "Clock",
    "Frame",
    "ImuSample",
    "ImuSource",
    "ObstacleLayout",
    "ObstacleSource",
    "PoseSample",
    "PoseSource",
    "Rect",
    "SampleError",
    "ThrusterCommand",
    "ThrusterSink",
    "ThrusterSinkError",
    "VelocityReference",
    "quaternion_from_yaw",
    "yaw_from_quaternion",
]
