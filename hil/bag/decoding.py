"""ROS 2 messages back into hil's samples and records (the reverse of :mod:`hil.bag.messages`).

:func:`to_record` turns a decoded message (a rosbags message object or anything
with the same attribute names) back into a sample or record; :data:`FAST_DECODERS`
go straight from a fixed-layout little-endian CDR payload to a sample, skipping
rosbags. Both read the fixed-layout types from the field table
(:mod:`hil.bag.field_table`); conventions are those of :mod:`hil.bag.messages`.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

import numpy as np

from hil.bag import cdr, topics
from hil.bag import field_table as ft
from hil.bag import typestore as ts
from hil.bag.errors import RecordValueError
from hil.bag.lab_frame import LabFrame
from hil.bag.messages import Record
from hil.core.arena_frame import ArenaTransform
from hil.core.clock import stamp_to_ns
from hil.core.geometry import quaternion_yaw
from hil.core.qtm_sample import QtmSample
from hil.core.records import (
    ControllerReady,
    ControllerSource,
    Decision,
    Event,
    EventLevel,
)
from hil.core.samples import (
    Frame,
    ObstacleLayout,
    SampleError,
    obstacle_rect,
)
from hil.core.shapes import Rect


def _yaw(q: Any) -> float:
    # Planar pose: yaw about z of the quaternion (x, y, z, w), wrapped to [-pi, pi).
    return quaternion_yaw(float(q.x), float(q.y), float(q.z), float(q.w))


def _from_message(layout: ft.FixedLayout) -> Callable[[Any], Record]:
    """Return the decoder of a fixed-layout message object (the field table's paths)."""

    def decode(msg: Any) -> Record:
        frame = None
        if layout.frame_from_header:
            try:
                frame = Frame(msg.header.frame_id)
            except ValueError:
                raise SampleError(
                    f"pose frame_id {msg.header.frame_id!r} is not one of "
                    f"{[f.value for f in Frame]!r}"
                ) from None
        t_ns = stamp_to_ns(msg.header.stamp)
        return ft.build(layout, t_ns, ft.message_fields(layout, msg), frame)

    return decode


def _decision(msg: Any) -> Decision:
    inputs = np.asarray(msg.safe_inputs, dtype=np.float64)
    if inputs.size % 3:
        raise RecordValueError(f"decision safe_inputs has {inputs.size} values, not k x 3")
    return Decision(
        t_ns=stamp_to_ns(msg.header.stamp),
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
        reference_index=int(msg.reference_index),
        first=bool(msg.first),
        report_age_s=_report_age(msg),
        report_t_ns=int(getattr(msg, "report_t_ns", -1)),
    )


def _report_age(msg: Any) -> float | None:
    """Return a decision's report age (s); None from a log written before it was recorded."""
    age = float(getattr(msg, "report_age_s", 0.0))
    return age if age > 0.0 else None


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
    return ObstacleLayout(stamp_to_ns(msg.header.stamp), tuple(_rectangle(p) for p in msg.real))


def _event(msg: Any) -> Event:
    try:
        level = EventLevel(int(msg.level))
    except ValueError:
        raise RecordValueError(f"event level {int(msg.level)!r} is not a known level") from None
    return Event(stamp_to_ns(msg.header.stamp), level, str(msg.code), str(msg.text))


def _controller_ready(msg: Any) -> ControllerReady:
    try:
        source = ControllerSource(int(msg.source))
    except ValueError:
        raise RecordValueError(f"controller source {int(msg.source)!r} is not known") from None
    return ControllerReady(
        stamp_to_ns(msg.header.stamp),
        int(msg.controller_version),
        float(msg.seconds),
        source,
        bool(msg.complete),
        float(msg.report_age_s),
        int(msg.layout_t_ns),
    )


def _qtm(msg: Any) -> QtmSample:
    return QtmSample(
        stamp_to_ns(msg.header.stamp),
        int(msg.qtm_timestamp_us),
        int(msg.frame_number),
        int(msg.body_index),
        str(msg.body),
        (float(msg.position_mm[0]), float(msg.position_mm[1]), float(msg.position_mm[2])),
        tuple(float(v) for v in msg.rotation),
        float(msg.residual_mm),
        int(msg.drop_rate),
        int(msg.out_of_sync_rate),
        int(msg.drops),
        int(msg.lost),
    )


def _planar(transform: Any) -> tuple[float, float, float]:
    """Return (x m, y m, yaw rad) of a geometry_msgs/Transform."""
    return (float(transform.translation.x), float(transform.translation.y),
            _yaw(transform.rotation))  # fmt: skip


def lab_frame_from_tf(msg: Any) -> LabFrame | None:
    """Return the lab frame a tf2_msgs/TFMessage of hil's recorder holds, else None.

    It needs ``<lab frame> -> arena``; ``mocap_body -> body`` (the body offset) is taken
    when present, else zero (the inverse of :func:`hil.bag.messages.tf_static_msg`).
    """
    arena = body = None
    for stamped in msg.transforms:
        if stamped.child_frame_id == topics.ARENA_FRAME:
            arena = (str(stamped.header.frame_id), _planar(stamped.transform))
        elif (stamped.child_frame_id, stamped.header.frame_id) == (
            topics.BODY_FRAME, topics.MOCAP_BODY_FRAME
        ):
            body = _planar(stamped.transform)
    if arena is None:
        return None
    frame_id, (north, east, yaw) = arena
    bx, by, byaw = body if body is not None else (0.0, 0.0, 0.0)
    return LabFrame(ArenaTransform(north, east, yaw, bx, by, byaw), frame_id or topics.LAB_FRAME)


_DECODERS: dict[str, Callable[[Any], Record]] = {
    **{layout.msgtype: _from_message(layout) for layout in ft.STAMPED_LAYOUTS},
    ts.DECISION: _decision,
    ts.OBSTACLE_LAYOUT: _layout,
    ts.EVENT: _event,
    ts.CONTROLLER_READY: _controller_ready,
    ts.QTM_6D: _qtm,
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


class _PayloadDecoder:
    """Decoder of a fixed-layout little-endian CDR payload (resolved on first use)."""

    __slots__ = ("_doubles", "_layout", "_offsets")

    def __init__(self, layout: ft.FixedLayout) -> None:
        self._layout = layout
        self._offsets: ft.Offsets | None = None
        self._doubles = struct.Struct("")

    def __call__(self, data: bytes) -> Record | None:
        off = self._offsets
        if off is None:
            off = self._offsets = ft.offsets(self._layout)
            self._doubles = struct.Struct(f"<{off.n_values}d")
        head = cdr.parse_header(data, off.child_frame)
        if head is None or len(data) != head.values_offset + self._doubles.size:
            return None
        values = self._doubles.unpack_from(data, head.values_offset)
        frame = None
        if self._layout.frame_from_header:
            try:
                frame = Frame(head.frame_id)
            except ValueError:
                return None  # the slow path words the error
        return ft.build(self._layout, head.t_ns, off.row_fields(values), frame)


FAST_DECODERS: dict[str, Callable[[bytes], Record | None]] = {
    layout.msgtype: _PayloadDecoder(layout) for layout in ft.STAMPED_LAYOUTS
}
"""Message type -> decoder straight from a CDR payload to a sample, for fixed layouts.

Each returns None when the payload is not the expected little-endian layout (a
foreign frame layout, big endian); the caller then decodes with rosbags.
Values a sample refuses (NaN) raise as in :func:`to_record`.
"""
