"""Converters between hil's samples and records and ROS 2 messages (CDR).

Writing: :func:`encode` turns one sample or record into ``(topic, payload)`` pairs
of little-endian CDR bytes: the fixed-layout types (pose, IMU, odometry, twist,
wrench, thruster commands) with precompiled ``struct`` layouts, the
variable-size ones (decisions, layouts, events) through rosbags'
``serialize_cdr``. It is the per-record reference; the recorder encodes the
fixed-layout types in bulk (:mod:`hil.bag.columnar`). Tests decode every
payload with rosbags and with the independent ``mcap_ros2`` decoder.

Reading: :func:`to_record` turns a decoded message (a rosbags message object or
anything with the same attribute names) back into a sample or record;
:data:`FAST_DECODERS` go straight from a fixed-layout payload to a sample.

Conventions: header stamps hold the sample time; the pose yaw is a quaternion
about z (x, y, z, w order, as ROS stores it); the IMU has no orientation
(``orientation_covariance[0] = -1``, REP 145). The lab's per-thruster Wrench
topics carry the tunnel command in force.x and each azimuth as the vector
``c (cos a, sin a)`` in force.x, force.y; that loses the sign of ``c``, so the
lossless copy on ``/hil/thrusters`` is the one read back.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np

from hil.bag import topics
from hil.bag import typestore as ts
from hil.bag.errors import RecordValueError
from hil.core.geometry import wrap_angle
from hil.core.records import (
    Decision,
    Event,
    EventLevel,
    ForceCommand,
    StateEstimate,
)
from hil.core.samples import (
    Frame,
    ImuSample,
    ObstacleLayout,
    PoseSample,
    SampleError,
    ThrusterCommand,
    VelocityReference,
    obstacle_rect,
)
from hil.core.shapes import Rect

Record = (
    PoseSample
    | ImuSample
    | VelocityReference
    | ThrusterCommand
    | StateEstimate
    | ForceCommand
    | Decision
    | ObstacleLayout
    | Event
)
"""Anything the recorder accepts."""

RECORD_TYPES: tuple[type, ...] = (
    PoseSample,
    ImuSample,
    VelocityReference,
    ThrusterCommand,
    StateEstimate,
    ForceCommand,
    Decision,
    ObstacleLayout,
    Event,
)

Encoded = list[tuple[str, bytes]]

_ENCAPSULATION = b"\x00\x01\x00\x00"  # CDR, little endian
_NS = 1_000_000_000


@cache
def _stamped(frame_id: str, n_doubles: int, child_frame_id: str | None = None) -> struct.Struct:
    """Return the layout: CDR header, stamp, frame_id [, child_frame_id], n float64.

    Alignment in CDR counts from the end of the 4-byte encapsulation header: the
    string lengths are 4-aligned, the float64 fields 8-aligned.
    """
    frame_len = len(frame_id.encode()) + 1  # strings carry their NUL
    fmt = f"<4siiI{frame_len}s"
    offset = 4 + 4 + 4 + frame_len  # sec, nanosec, string length, string
    if child_frame_id is not None:
        child_len = len(child_frame_id.encode()) + 1
        pad = _pad(offset, 4)
        fmt += f"{pad}xI{child_len}s"
        offset += pad + 4 + child_len
    fmt += f"{_pad(offset, 8)}x{n_doubles}d"
    return struct.Struct(fmt)


def _pad(offset: int, align: int) -> int:
    return (-offset) % align


_WRENCH = struct.Struct("<4s6d")


def _stamp(t_ns: int) -> tuple[int, int]:
    if t_ns < 0 or t_ns >= 2**31 * _NS:
        raise RecordValueError(f"time {t_ns!r} ns does not fit a ROS stamp (int32 seconds >= 0)")
    sec, nsec = divmod(int(t_ns), _NS)
    return sec, nsec


def _encode_header_only(
    layout: struct.Struct, frame_id: str, t_ns: int, values: tuple[float, ...]
) -> bytes:
    sec, nsec = _stamp(t_ns)
    frame = frame_id.encode() + b"\x00"
    return layout.pack(_ENCAPSULATION, sec, nsec, len(frame), frame, *values)


def encode_pose(sample: PoseSample) -> Encoded:
    """Encode a pose as PoseWithCovarianceStamped in the sample's frame (covariance zero)."""
    half = 0.5 * sample.yaw_rad
    values = (sample.x_m, sample.y_m, 0.0, 0.0, 0.0, math.sin(half), math.cos(half), *_ZERO36)
    layout = _stamped(sample.frame.value, 43)
    return [(topics.POSE, _encode_header_only(layout, sample.frame.value, sample.t_ns, values))]


_ZERO36 = (0.0,) * 36
_ZERO9 = (0.0,) * 9
_NO_ORIENTATION = (0.0, 0.0, 0.0, 1.0, -1.0, *(0.0,) * 8)


def encode_imu(sample: ImuSample) -> Encoded:
    """Encode an IMU sample as sensor_msgs/Imu (no orientation, covariances zero)."""
    values = (
        *_NO_ORIENTATION,
        0.0,
        0.0,
        sample.yaw_rate_radps,
        *_ZERO9,
        sample.accel_x_mps2,
        sample.accel_y_mps2,
        0.0,
        *_ZERO9,
    )
    layout = _stamped(topics.IMU_FRAME, 37)
    return [(topics.IMU, _encode_header_only(layout, topics.IMU_FRAME, sample.t_ns, values))]


def encode_velocity_reference(sample: VelocityReference) -> Encoded:
    """Encode nu_ref as TwistStamped in the body frame (linear.x = u, .y = v, angular.z = r)."""
    values = (sample.surge_mps, sample.sway_mps, 0.0, 0.0, 0.0, sample.yaw_rate_radps)
    layout = _stamped(topics.BODY_FRAME, 6)
    payload = _encode_header_only(layout, topics.BODY_FRAME, sample.t_ns, values)
    return [(topics.VELOCITY_COMMAND, payload)]


def encode_force(record: ForceCommand) -> Encoded:
    """Encode tau as WrenchStamped in the body frame (force.x = X, .y = Y, torque.z = N)."""
    values = (record.surge_n, record.sway_n, 0.0, 0.0, 0.0, record.yaw_nm)
    layout = _stamped(topics.BODY_FRAME, 6)
    payload = _encode_header_only(layout, topics.BODY_FRAME, record.t_ns, values)
    return [(topics.FORCE_COMMAND, payload)]


def encode_state_estimate(record: StateEstimate) -> Encoded:
    """Encode the estimate as nav_msgs/Odometry: pose in the arena, twist in the body frame."""
    half = 0.5 * record.yaw_rad
    values = (
        record.x_m,
        record.y_m,
        0.0,
        0.0,
        0.0,
        math.sin(half),
        math.cos(half),
        *_ZERO36,
        record.surge_mps,
        record.sway_mps,
        0.0,
        0.0,
        0.0,
        record.yaw_rate_radps,
        *_ZERO36,
    )
    layout = _stamped(topics.ARENA_FRAME, 85, topics.BODY_FRAME)
    sec, nsec = _stamp(record.t_ns)
    frame = topics.ARENA_FRAME.encode() + b"\x00"
    child = topics.BODY_FRAME.encode() + b"\x00"
    payload = layout.pack(_ENCAPSULATION, sec, nsec, len(frame), frame, len(child), child, *values)
    return [(topics.ODOM, payload)]


_THRUSTERS = _stamped(topics.BODY_FRAME, 5)


def encode_thrusters(sample: ThrusterCommand) -> Encoded:
    """Encode thruster commands on the lab's three Wrench topics and on /hil/thrusters."""
    tunnel = _WRENCH.pack(_ENCAPSULATION, sample.tunnel, 0.0, 0.0, 0.0, 0.0, 0.0)
    port = _WRENCH.pack(
        _ENCAPSULATION,
        sample.port * math.cos(sample.port_angle_rad),
        sample.port * math.sin(sample.port_angle_rad),
        0.0,
        0.0,
        0.0,
        0.0,
    )
    starboard = _WRENCH.pack(
        _ENCAPSULATION,
        sample.starboard * math.cos(sample.starboard_angle_rad),
        sample.starboard * math.sin(sample.starboard_angle_rad),
        0.0,
        0.0,
        0.0,
        0.0,
    )
    values = (
        sample.tunnel,
        sample.port,
        sample.starboard,
        sample.port_angle_rad,
        sample.starboard_angle_rad,
    )
    full = _encode_header_only(_THRUSTERS, topics.BODY_FRAME, sample.t_ns, values)
    return [
        (topics.THRUSTER_TUNNEL, tunnel),
        (topics.THRUSTER_PORT, port),
        (topics.THRUSTER_STARBOARD, starboard),
        (topics.THRUSTERS, full),
    ]


def _header(t_ns: int, frame_id: str) -> Any:
    store = ts.typestore()
    sec, nsec = _stamp(t_ns)
    time_cls = store.types["builtin_interfaces/msg/Time"]
    header_cls = store.types["std_msgs/msg/Header"]
    return header_cls(stamp=time_cls(sec=sec, nanosec=nsec), frame_id=frame_id)


def decision_msg(record: Decision) -> Any:
    """Return the hil_msgs/Decision message object (rosbags) of a decision."""
    cls = ts.typestore().types[ts.DECISION]
    return cls(
        header=_header(record.t_ns, topics.ARENA_FRAME),
        x=record.state[0],
        y=record.state[1],
        psi=record.state[2],
        cell=record.cell,
        value=record.value,
        winning=record.winning,
        safe_inputs=np.array(record.safe_inputs, dtype=np.float64).reshape(-1),
        safe_input_indices=np.array(record.safe_input_indices, dtype=np.int32),
        chosen_index=record.chosen_index,
        chosen_input=np.array(record.chosen_input, dtype=np.float64),
        controller_version=record.controller_version,
        scenario_hash=record.scenario_hash,
    )


def _rectangle_msg(rect: Rect) -> Any:
    # Counter-clockwise from (x_min, y_min); read back by _rectangle.
    cls = ts.typestore().types[ts.POLYGON_2D]
    xs = np.array([rect.x_min_m, rect.x_max_m, rect.x_max_m, rect.x_min_m])
    ys = np.array([rect.y_min_m, rect.y_min_m, rect.y_max_m, rect.y_max_m])
    return cls(name="", x=xs, y=ys)


def obstacle_layout_msg(record: ObstacleLayout) -> Any:
    """Return the hil_msgs/ObstacleLayout message object of a layout.

    Each rectangle becomes a 4-vertex polygon in ``real``; ``inflated`` is left
    empty (the inflation follows from the scenario).
    """
    cls = ts.typestore().types[ts.OBSTACLE_LAYOUT]
    return cls(
        header=_header(record.t_ns, topics.ARENA_FRAME),
        real=[_rectangle_msg(r) for r in record.obstacles],
        inflated=[],
    )


def event_msg(record: Event) -> Any:
    """Return the hil_msgs/Event message object of an event."""
    cls = ts.typestore().types[ts.EVENT]
    return cls(
        header=_header(record.t_ns, ""),
        level=int(record.level),
        code=record.code,
        text=record.text,
    )


def _serialized(topic: str, typename: str, msg: Any) -> Encoded:
    return [(topic, bytes(ts.typestore().serialize_cdr(msg, typename)))]


def encode_decision(record: Decision) -> Encoded:
    """Encode a decision as hil_msgs/Decision on /hil/decision."""
    return _serialized(topics.DECISION, ts.DECISION, decision_msg(record))


def encode_obstacles(record: ObstacleLayout) -> Encoded:
    """Encode a layout as hil_msgs/ObstacleLayout on /hil/obstacles."""
    return _serialized(topics.OBSTACLES, ts.OBSTACLE_LAYOUT, obstacle_layout_msg(record))


def encode_event(record: Event) -> Encoded:
    """Encode an event as hil_msgs/Event on /hil/events."""
    return _serialized(topics.EVENTS, ts.EVENT, event_msg(record))


ENCODERS: dict[type, Callable[[Any], Encoded]] = {
    PoseSample: encode_pose,
    ImuSample: encode_imu,
    VelocityReference: encode_velocity_reference,
    ThrusterCommand: encode_thrusters,
    StateEstimate: encode_state_estimate,
    ForceCommand: encode_force,
    Decision: encode_decision,
    ObstacleLayout: encode_obstacles,
    Event: encode_event,
}


def encode(record: Record) -> Encoded:
    """Encode a sample or record as ROS 2 CDR messages.

    Args:
        record: Any of :data:`RECORD_TYPES`.

    Returns:
        ``(topic, payload)`` pairs; one pair, or four for thruster commands.

    Raises:
        RecordValueError: Unknown record type or a time that does not fit a ROS stamp.
    """
    try:
        encoder = ENCODERS[type(record)]
    except KeyError:
        raise RecordValueError(
            f"cannot record {type(record).__name__!r}: expected one of "
            f"{sorted(t.__name__ for t in RECORD_TYPES)!r}"
        ) from None
    return encoder(record)


# ---------------------------------------------------------------- reading


def _t_ns(header: Any) -> int:
    return int(header.stamp.sec) * _NS + int(header.stamp.nanosec)


def _yaw(q: Any) -> float:
    # Planar pose: yaw about z of the quaternion (x, y, z, w), wrapped to [-pi, pi).
    siny = 2.0 * (q.w * q.z + q.x * q.y)
    cosy = 1.0 - 2.0 * (q.y * q.y + q.z * q.z)
    return float(wrap_angle(math.atan2(siny, cosy)))


def _pose(msg: Any) -> PoseSample:
    try:
        frame = Frame(msg.header.frame_id)
    except ValueError:
        raise SampleError(
            f"pose frame_id {msg.header.frame_id!r} is not one of {[f.value for f in Frame]!r}"
        ) from None
    p = msg.pose.pose
    return PoseSample(
        _t_ns(msg.header), float(p.position.x), float(p.position.y), _yaw(p.orientation), frame
    )


def _imu(msg: Any) -> ImuSample:
    return ImuSample(
        _t_ns(msg.header),
        float(msg.linear_acceleration.x),
        float(msg.linear_acceleration.y),
        float(msg.angular_velocity.z),
    )


def _odom(msg: Any) -> StateEstimate:
    p = msg.pose.pose
    tw = msg.twist.twist
    return StateEstimate(
        _t_ns(msg.header),
        float(p.position.x),
        float(p.position.y),
        _yaw(p.orientation),
        float(tw.linear.x),
        float(tw.linear.y),
        float(tw.angular.z),
    )


def _twist(msg: Any) -> VelocityReference:
    tw = msg.twist
    return VelocityReference(
        _t_ns(msg.header), float(tw.linear.x), float(tw.linear.y), float(tw.angular.z)
    )


def _wrench(msg: Any) -> ForceCommand:
    w = msg.wrench
    return ForceCommand(_t_ns(msg.header), float(w.force.x), float(w.force.y), float(w.torque.z))


def _thrusters(msg: Any) -> ThrusterCommand:
    return ThrusterCommand(
        _t_ns(msg.header),
        float(msg.tunnel),
        float(msg.port),
        float(msg.starboard),
        float(msg.port_angle),
        float(msg.starboard_angle),
    )


def _decision(msg: Any) -> Decision:
    inputs = np.asarray(msg.safe_inputs, dtype=np.float64)
    if inputs.size % 3:
        raise RecordValueError(f"decision safe_inputs has {inputs.size} values, not k x 3")
    return Decision(
        t_ns=_t_ns(msg.header),
        state=(float(msg.x), float(msg.y), float(msg.psi)),
        cell=int(msg.cell),
        value=float(msg.value),
        winning=bool(msg.winning),
        safe_inputs=tuple((float(u), float(v), float(r)) for u, v, r in inputs.reshape(-1, 3)),
        safe_input_indices=tuple(int(i) for i in np.asarray(msg.safe_input_indices)),
        chosen_index=int(msg.chosen_index),
        chosen_input=tuple(float(c) for c in np.asarray(msg.chosen_input)),  # type: ignore[arg-type]
        controller_version=int(msg.controller_version),
        scenario_hash=str(msg.scenario_hash),
    )


def _rectangle(msg: Any) -> Rect:
    xs = np.asarray(msg.x, dtype=np.float64)
    ys = np.asarray(msg.y, dtype=np.float64)
    if xs.shape != (4,) or ys.shape != (4,):
        raise RecordValueError(
            f"obstacle polygon {msg.name!r} has {xs.size} x and {ys.size} y values, "
            "not the 4 corners of a rectangle"
        )
    rect = obstacle_rect(float(xs.min()), float(xs.max()), float(ys.min()), float(ys.max()))
    corners_x = set(xs.tolist()) <= {rect.x_min_m, rect.x_max_m}
    corners_y = set(ys.tolist()) <= {rect.y_min_m, rect.y_max_m}
    if not (corners_x and corners_y):
        raise RecordValueError(
            f"obstacle polygon {msg.name!r} is not an axis-aligned rectangle: "
            f"x={xs.tolist()!r}, y={ys.tolist()!r}"
        )
    return rect


def _layout(msg: Any) -> ObstacleLayout:
    return ObstacleLayout(_t_ns(msg.header), tuple(_rectangle(p) for p in msg.real))


def _event(msg: Any) -> Event:
    try:
        level = EventLevel(int(msg.level))
    except ValueError:
        raise RecordValueError(f"event level {int(msg.level)!r} is not a known level") from None
    return Event(_t_ns(msg.header), level, str(msg.code), str(msg.text))


_DECODERS: dict[str, Callable[[Any], Record]] = {
    topics.POSE_TYPE: _pose,
    topics.IMU_TYPE: _imu,
    topics.ODOM_TYPE: _odom,
    topics.TWIST_STAMPED_TYPE: _twist,
    topics.WRENCH_STAMPED_TYPE: _wrench,
    ts.THRUSTER_COMMANDS: _thrusters,
    ts.DECISION: _decision,
    ts.OBSTACLE_LAYOUT: _layout,
    ts.EVENT: _event,
}

SAMPLE_TYPES: frozenset[str] = frozenset(_DECODERS)
"""Message types :func:`to_record` converts."""


def to_record(msgtype: str, msg: Any) -> Record | None:
    """Convert a decoded message to a sample or record.

    Args:
        msgtype: Full message type name, e.g. ``"sensor_msgs/msg/Imu"``.
        msg: The decoded message (rosbags object or same attribute names).

    Returns:
        The sample or record, or None for types without one (e.g. the lab's
        per-thruster Wrench topics, which ``/hil/thrusters`` duplicates losslessly).

    Raises:
        SampleError: The message holds a value a sample refuses (NaN, unknown frame).
        RecordValueError: The message holds a value a record refuses.
    """
    decoder = _DECODERS.get(msgtype)
    return None if decoder is None else decoder(msg)


# ---------------------------------------------------------------- fast reading

_STAMP_LEN = struct.Struct("<iII")  # sec, nanosec, frame_id length (with NUL)
_LEN = struct.Struct("<I")


@cache
def _doubles(n: int) -> struct.Struct:
    return struct.Struct(f"<{n}d")


def _unpack_stamped(
    data: bytes, n: int, child: bool = False
) -> tuple[int, str, tuple[float, ...]] | None:
    """Unpack header + n float64 of a little-endian CDR payload; None if it does not fit."""
    if len(data) < 16 or data[1] != 1:  # encapsulation 0x0001: CDR little endian
        return None
    sec, nsec, str_len = _STAMP_LEN.unpack_from(data, 4)
    offset = 16 + str_len
    frame = data[16 : offset - 1].decode("utf-8", "replace")
    if child:
        offset += _pad(offset - 4, 4)
        if offset + 4 > len(data):
            return None
        (child_len,) = _LEN.unpack_from(data, offset)
        offset += 4 + child_len
    offset += _pad(offset - 4, 8)
    if len(data) != offset + 8 * n:
        return None
    return sec * _NS + nsec, frame, _doubles(n).unpack_from(data, offset)


def _yaw_xyzw(x: float, y: float, z: float, w: float) -> float:
    return float(wrap_angle(math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))))


def _fast_pose(data: bytes) -> Record | None:
    got = _unpack_stamped(data, 7 + 36)
    if got is None:
        return None
    t_ns, frame_id, v = got
    try:
        frame = Frame(frame_id)
    except ValueError:
        return None  # the slow path words the error
    return PoseSample(t_ns, v[0], v[1], _yaw_xyzw(v[3], v[4], v[5], v[6]), frame)


def _fast_imu(data: bytes) -> Record | None:
    got = _unpack_stamped(data, 37)
    if got is None:
        return None
    t_ns, _, v = got
    return ImuSample(t_ns, v[25], v[26], v[15])


def _fast_odom(data: bytes) -> Record | None:
    got = _unpack_stamped(data, 85, child=True)
    if got is None:
        return None
    t_ns, _, v = got
    return StateEstimate(t_ns, v[0], v[1], _yaw_xyzw(v[3], v[4], v[5], v[6]), v[43], v[44], v[48])


def _fast_twist(data: bytes) -> Record | None:
    got = _unpack_stamped(data, 6)
    if got is None:
        return None
    t_ns, _, v = got
    return VelocityReference(t_ns, v[0], v[1], v[5])


def _fast_wrench(data: bytes) -> Record | None:
    got = _unpack_stamped(data, 6)
    if got is None:
        return None
    t_ns, _, v = got
    return ForceCommand(t_ns, v[0], v[1], v[5])


def _fast_thrusters(data: bytes) -> Record | None:
    got = _unpack_stamped(data, 5)
    if got is None:
        return None
    t_ns, _, v = got
    return ThrusterCommand(t_ns, *v)


FAST_DECODERS: dict[str, Callable[[bytes], Record | None]] = {
    topics.POSE_TYPE: _fast_pose,
    topics.IMU_TYPE: _fast_imu,
    topics.ODOM_TYPE: _fast_odom,
    topics.TWIST_STAMPED_TYPE: _fast_twist,
    topics.WRENCH_STAMPED_TYPE: _fast_wrench,
    ts.THRUSTER_COMMANDS: _fast_thrusters,
}
"""Message type -> decoder straight from a CDR payload to a sample, for fixed layouts.

Each returns None when the payload is not the expected little-endian layout (a
foreign frame layout, big endian); the caller then decodes with rosbags.
Values a sample refuses (NaN) raise as in :func:`to_record`.
"""
