"""An independent per-record reference for the fixed-layout codecs: rosbags message objects.

Hil encodes and decodes its fixed-layout messages from one field table
(:mod:`hil.bag.field_table`). To check that table, this module builds each record's
messages by hand, field by field, as rosbags message objects, for rosbags' own
serializer: the conventions written out once more, independently (stamp = sample
time, yaw as a quaternion about z, the IMU without orientation, the commands
unstamped on the lab's topics and stamped on ``/hil/...``, the lab's per-thruster
Wrench vectors).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from hil.bag import topics
from hil.bag import typestore as ts
from hil.bag.lab_frame import DEFAULT_LAB_FRAME, LabFrame
from hil.core.records import ForceCommand, StateEstimate
from hil.core.samples import Frame, ImuSample, PoseSample, ThrusterCommand, VelocityReference


def _t(name: str) -> Any:
    return ts.typestore().types[name]


def _header(t_ns: int, frame_id: str) -> Any:
    sec, nsec = divmod(t_ns, 1_000_000_000)
    stamp = _t("builtin_interfaces/msg/Time")(sec=sec, nanosec=nsec)
    return _t("std_msgs/msg/Header")(stamp=stamp, frame_id=frame_id)


def _vector(x: float, y: float, z: float = 0.0) -> Any:
    return _t("geometry_msgs/msg/Vector3")(x=x, y=y, z=z)


def _pose_with_covariance(x_m: float, y_m: float, yaw_rad: float) -> Any:
    q = _t("geometry_msgs/msg/Quaternion")(
        x=0.0, y=0.0, z=math.sin(yaw_rad / 2), w=math.cos(yaw_rad / 2)
    )
    pose = _t("geometry_msgs/msg/Pose")(
        position=_t("geometry_msgs/msg/Point")(x=x_m, y=y_m, z=0.0), orientation=q
    )
    return _t("geometry_msgs/msg/PoseWithCovariance")(pose=pose, covariance=np.zeros(36))


def _twist(u: float, v: float, r: float) -> Any:
    return _t("geometry_msgs/msg/Twist")(linear=_vector(u, v), angular=_vector(0.0, 0.0, r))


def _wrench(fx: float, fy: float, n: float) -> Any:
    return _t("geometry_msgs/msg/Wrench")(force=_vector(fx, fy), torque=_vector(0.0, 0.0, n))


def _poses(p: PoseSample, lab: LabFrame) -> list[tuple[str, Any]]:
    in_lab = p if p.frame is Frame.LAB_NED else lab.transform.to_lab(p)
    in_arena = p if p.frame is Frame.ARENA else lab.transform.to_arena(p)
    cls = _t(topics.POSE_TYPE)
    return [
        (topics.POSE, cls(header=_header(p.t_ns, lab.frame_id),
                          pose=_pose_with_covariance(in_lab.x_m, in_lab.y_m, in_lab.yaw_rad))),
        (topics.HIL_POSE, cls(header=_header(p.t_ns, topics.ARENA_FRAME),
                              pose=_pose_with_covariance(in_arena.x_m, in_arena.y_m,
                                                         in_arena.yaw_rad))),
    ]  # fmt: skip


def _imu(s: ImuSample) -> list[tuple[str, Any]]:
    covariance = np.zeros(9)
    unknown = covariance.copy()
    unknown[0] = -1.0  # REP 145: no orientation
    msg = _t(topics.IMU_TYPE)(
        header=_header(s.t_ns, topics.IMU_FRAME),
        orientation=_t("geometry_msgs/msg/Quaternion")(x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=unknown,
        angular_velocity=_vector(0.0, 0.0, s.yaw_rate_radps),
        angular_velocity_covariance=covariance,
        linear_acceleration=_vector(s.accel_x_mps2, s.accel_y_mps2),
        linear_acceleration_covariance=covariance,
    )
    return [(topics.IMU, msg)]


def _odom(e: StateEstimate) -> list[tuple[str, Any]]:
    twist = _t("geometry_msgs/msg/TwistWithCovariance")(
        twist=_twist(e.surge_mps, e.sway_mps, e.yaw_rate_radps), covariance=np.zeros(36)
    )
    msg = _t(topics.ODOM_TYPE)(
        header=_header(e.t_ns, topics.ARENA_FRAME),
        child_frame_id=topics.BODY_FRAME,
        pose=_pose_with_covariance(e.x_m, e.y_m, e.yaw_rad),
        twist=twist,
    )
    return [(topics.HIL_ODOM, msg)]


def _velocity(r: VelocityReference) -> list[tuple[str, Any]]:
    twist = _twist(r.surge_mps, r.sway_mps, r.yaw_rate_radps)
    stamped = _t(topics.TWIST_STAMPED_TYPE)(header=_header(r.t_ns, topics.BODY_FRAME), twist=twist)
    return [(topics.VELOCITY_COMMAND, twist), (topics.HIL_VELOCITY_COMMAND, stamped)]


def _force(f: ForceCommand) -> list[tuple[str, Any]]:
    wrench = _wrench(f.surge_n, f.sway_n, f.yaw_nm)
    stamped = _t(topics.WRENCH_STAMPED_TYPE)(
        header=_header(f.t_ns, topics.BODY_FRAME), wrench=wrench
    )
    return [(topics.FORCE_COMMAND, wrench), (topics.HIL_FORCE_COMMAND, stamped)]


def _thrusters(c: ThrusterCommand) -> list[tuple[str, Any]]:
    def azimuth(thrust: float, angle: float) -> Any:
        return _wrench(thrust * math.cos(angle), thrust * math.sin(angle), 0.0)

    full = _t(ts.THRUSTER_COMMANDS)(
        header=_header(c.t_ns, topics.BODY_FRAME), tunnel=c.tunnel, port=c.port,
        starboard=c.starboard, port_angle=c.port_angle_rad,
        starboard_angle=c.starboard_angle_rad,
    )  # fmt: skip
    return [
        (topics.THRUSTER_TUNNEL, _wrench(c.tunnel, 0.0, 0.0)),
        (topics.THRUSTER_PORT, azimuth(c.port, c.port_angle_rad)),
        (topics.THRUSTER_STARBOARD, azimuth(c.starboard, c.starboard_angle_rad)),
        (topics.THRUSTERS, full),
    ]


FIXED_TYPES = (PoseSample, ImuSample, StateEstimate, VelocityReference, ForceCommand,
               ThrusterCommand)  # fmt: skip
"""The record types of the fixed layouts."""


def reference_messages(record: Any, lab: LabFrame = DEFAULT_LAB_FRAME) -> list[tuple[str, Any]]:
    """Return a fixed-layout record's (topic, rosbags message object) pairs, as hil records them."""
    if isinstance(record, PoseSample):
        return _poses(record, lab)
    builders: dict[type, Callable[[Any], list[tuple[str, Any]]]] = {
        ImuSample: _imu, StateEstimate: _odom, VelocityReference: _velocity,
        ForceCommand: _force, ThrusterCommand: _thrusters,
    }  # fmt: skip
    return builders[type(record)](record)


def reference_payloads(record: Any, lab: LabFrame = DEFAULT_LAB_FRAME) -> list[tuple[str, bytes]]:
    """Return :func:`reference_messages` serialized by rosbags (little-endian CDR)."""
    store = ts.typestore()
    return [
        (topic, bytes(store.serialize_cdr(msg, topics.TOPIC_TYPES[topic])))
        for topic, msg in reference_messages(record, lab)
    ]
