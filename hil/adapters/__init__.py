"""Adapters (layer 6): the world's interfaces (typing.Protocol) and their backends.

:mod:`~hil.adapters.interfaces` declares the pose, IMU, obstacle and thruster
interfaces and the clock; the backends are :mod:`hil.adapters.sim` (the simulated
world), :mod:`hil.adapters.log` (a recorded run, read by :mod:`hil.bag.run_data`),
:mod:`hil.adapters.ros` (rclpy, imported lazily) and :mod:`hil.adapters.qtm` (the pose
straight from Qualisys QTM's real-time protocol, qtm-rt imported lazily; its frame
arithmetic in :mod:`hil.adapters.qtm_feed`), modules of their own so that importing the
interfaces pulls in neither numba nor rclpy nor qtm-rt. May import bag, sim, controllers,
model, scenarios and core; the runtime builds on it.
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
