"""Hil's samples and records as ROS 2 messages (CDR): what is recorded, and its encoding.

:data:`Record` is anything the recorder accepts. :func:`encode` turns one
sample or record into ``(topic, payload)`` pairs of little-endian CDR bytes: the
fixed-layout types (pose, IMU, odometry, twist, wrench, thruster commands) through the
bulk encoder generated from the field table (:mod:`hil.bag.columnar`,
:mod:`hil.bag.field_table`), the variable-size ones (decisions, layouts, events,
controllers, QTM frames, the static transforms) as rosbags message objects through
rosbags' ``serialize_cdr``. Tests check every payload against rosbags' serializer fed
from independent message builders, and decode it with rosbags and with the
independent ``mcap_ros2`` decoder.

Reading them back is :mod:`hil.bag.decoding`.

Where each goes (:mod:`hil.bag.topics`): a pose to the lab's topic in the lab's frame
(mapped back through the :class:`~hil.bag.lab_frame.LabFrame`'s transform when it is an
arena pose) and to ``/hil/pose`` in the arena; the velocity and force commands unstamped
to the lab's topics and stamped to ``/hil/...``; the estimate to ``/hil/odom``.

Conventions: header stamps hold the sample time (:mod:`hil.bag.cdr`); the pose yaw is a
quaternion about z (x, y, z, w order, as ROS stores it); the IMU has no orientation
(``orientation_covariance[0] = -1``, REP 145). The lab's per-thruster Wrench
topics carry the tunnel command in force.x and each azimuth as the vector
``c (cos a, sin a)`` in force.x, force.y (:mod:`hil.core.azimuth`); that loses the sign
of ``c``, so the lossless copy on ``/hil/thrusters`` is the one read back.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from hil.bag import cdr, topics
from hil.bag import typestore as ts
from hil.bag.columnar import BULK_ENCODERS, encode_poses
from hil.bag.errors import RecordValueError
from hil.bag.lab_frame import DEFAULT_LAB_FRAME, LabFrame
from hil.core.geometry import yaw_quaternion
from hil.core.qtm_sample import QtmSample
from hil.core.records import (
    ControllerReady,
    Decision,
    Event,
    ForceCommand,
    StateEstimate,
)
from hil.core.samples import (
    ImuSample,
    ObstacleLayout,
    PoseSample,
    ThrusterCommand,
    VelocityReference,
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
    | ControllerReady
    | QtmSample
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
    ControllerReady,
    QtmSample,
)

Encoded = list[tuple[str, bytes]]
"""(topic, CDR payload) pairs."""


def _header(t_ns: int, frame_id: str) -> Any:
    store = ts.typestore()
    sec, nsec = cdr.stamp(t_ns)
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
        reference_index=record.reference_index,
        first=record.first,
        report_age_s=0.0 if record.report_age_s is None else record.report_age_s,
        report_t_ns=record.report_t_ns,
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


def controller_ready_msg(record: ControllerReady) -> Any:
    """Return the hil_msgs/ControllerReady message object of a controller taken."""
    cls = ts.typestore().types[ts.CONTROLLER_READY]
    return cls(
        header=_header(record.t_ns, ""),
        controller_version=record.version,
        seconds=record.seconds,
        source=int(record.source),
        complete=record.complete,
        report_age_s=record.report_age_s,
        layout_t_ns=record.layout_t_ns,
    )


def qtm_msg(record: QtmSample) -> Any:
    """Return the hil_msgs/Qtm6D message object of a QTM 6D frame."""
    cls = ts.typestore().types[ts.QTM_6D]
    return cls(
        header=_header(record.t_ns, topics.QTM_FRAME),
        qtm_timestamp_us=record.timestamp_us,
        frame_number=record.frame_number,
        body_index=record.body_index,
        body=record.body,
        position_mm=np.array(record.position_mm, dtype=np.float64),
        rotation=np.array(record.rotation, dtype=np.float64),
        residual_mm=record.residual_mm,
        drop_rate=record.drop_rate,
        out_of_sync_rate=record.out_of_sync_rate,
        drops=record.drops,
        lost=record.lost,
    )


def _transform_msg(t_ns: int, parent: str, child: str, x_m: float, y_m: float,
                   yaw_rad: float) -> Any:
    store = ts.typestore().types
    qx, qy, qz, qw = yaw_quaternion(yaw_rad)
    return store["geometry_msgs/msg/TransformStamped"](
        header=_header(t_ns, parent),
        child_frame_id=child,
        transform=store["geometry_msgs/msg/Transform"](
            translation=store["geometry_msgs/msg/Vector3"](x=x_m, y=y_m, z=0.0),
            rotation=store["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
        ),
    )


def tf_static_msg(t_ns: int, lab: LabFrame) -> Any:
    """Return the tf2_msgs/TFMessage of the static frames at `t_ns`.

    Two transforms, each the child frame's pose in its parent (REP 105 style):
    ``lab.frame_id -> arena`` (the arena origin (north, east) m and its x axis's yaw
    from north) and ``mocap_body -> body`` (the vessel's body origin in the mocap
    body (forward, starboard) m and its heading offset).
    """
    t = lab.transform
    return ts.typestore().types[topics.TF_TYPE](transforms=[
        _transform_msg(t_ns, lab.frame_id, topics.ARENA_FRAME, t.origin_north_m,
                       t.origin_east_m, t.yaw_rad),
        _transform_msg(t_ns, topics.MOCAP_BODY_FRAME, topics.BODY_FRAME, t.body_offset_x_m,
                       t.body_offset_y_m, t.body_yaw_rad),
    ])  # fmt: skip


def encode_tf_static(t_ns: int, lab: LabFrame) -> Encoded:
    """Encode the static frames (:func:`tf_static_msg`) on /tf_static."""
    cdr.stamp(t_ns)
    return _serialized(topics.TF_STATIC, topics.TF_TYPE, tf_static_msg(t_ns, lab))


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


def encode_controller_ready(record: ControllerReady) -> Encoded:
    """Encode a controller taken as hil_msgs/ControllerReady on /hil/controllers."""
    return _serialized(topics.CONTROLLERS, ts.CONTROLLER_READY, controller_ready_msg(record))


def encode_qtm(record: QtmSample) -> Encoded:
    """Encode a QTM 6D frame as hil_msgs/Qtm6D on /hil/qtm/6d."""
    return _serialized(topics.QTM_6D, ts.QTM_6D, qtm_msg(record))


ENCODERS: dict[type, Callable[[Any], Encoded]] = {
    Decision: encode_decision,
    ObstacleLayout: encode_obstacles,
    Event: encode_event,
    ControllerReady: encode_controller_ready,
    QtmSample: encode_qtm,
}
"""Record type -> encoder, for the variable-size types (the others: :data:`BULK_ENCODERS`)."""


def encode(record: Record, lab: LabFrame = DEFAULT_LAB_FRAME) -> Encoded:
    """Encode a sample or record as ROS 2 CDR messages.

    Args:
        record: Any of :data:`RECORD_TYPES`.
        lab: The lab's pose frame (for poses).

    Returns:
        ``(topic, payload)`` pairs: one, two for poses and commands (the lab's topic and
        hil's), four for thruster commands.

    Raises:
        RecordValueError: Unknown record type or a time that does not fit a ROS stamp.
    """
    if isinstance(record, PoseSample):
        blocks = encode_poses([record], lab)
    elif type(record) in BULK_ENCODERS:
        blocks = BULK_ENCODERS[type(record)]([record])
    elif type(record) in ENCODERS:
        return ENCODERS[type(record)](record)
    else:
        raise RecordValueError(
            f"cannot record {type(record).__name__!r}: expected one of "
            f"{sorted(t.__name__ for t in RECORD_TYPES)!r}"
        )
    return [(block.topic, block.payloads[0].tobytes()) for block in blocks]
