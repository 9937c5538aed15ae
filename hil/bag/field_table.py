"""The one field table of hil's fixed-layout messages, and what every codec reads of it.

The high-rate streams (pose, IMU, estimate, commands) are ROS messages whose data,
after the header and frame ids, is a block of float64 only. :data:`LAYOUTS` says, per
message type, which record attribute sits at which field path of the message
(``"pose.pose.position.x"``); the byte layout (each field's index in the float64
block, the block's length, whether a header and a child frame id precede it) is
derived from the message definition in rosbags' typestore, the way rosbags generates
its own codecs from its field definitions. A field whose path names a
``geometry_msgs/Quaternion`` is a yaw (rad): encoded as the rotation about z
(:func:`hil.core.geometry.yaw_quaternion`), decoded as its yaw.

Every fixed-layout codec reads this table: the bulk encoder
(:mod:`hil.bag.columnar`, which :func:`hil.bag.messages.encode` uses for these types
too), the per-message decoders (:mod:`hil.bag.decoding`: from a payload and from a
rosbags message object), the bulk decoder (:mod:`hil.bag.columns`), the run loader's
streams (:data:`hil.bag.run_data.FIELDS`) and the lab's unstamped commands
(:mod:`hil.bag.lab_streams`). Adding a field is one line here (and in the ``.msg``
file for hil's own types). The CDR details are :mod:`hil.bag.cdr`.
"""

from __future__ import annotations

import functools
import operator
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype

from hil.bag import topics
from hil.bag import typestore as ts
from hil.bag.errors import SchemaError
from hil.core.arrays import FloatArray
from hil.core.geometry import quaternion_yaw, quaternion_yaws, yaw_quaternions
from hil.core.records import ForceCommand, StateEstimate
from hil.core.samples import Frame, ImuSample, PoseSample, ThrusterCommand, VelocityReference

FixedRecord = (
    PoseSample | ImuSample | StateEstimate | VelocityReference | ForceCommand | ThrusterCommand
)
"""The records a fixed-layout message holds."""

_QUATERNION = "geometry_msgs/msg/Quaternion"
_HEADER = "std_msgs/msg/Header"


@dataclass(frozen=True, slots=True)
class FixedLayout:
    """One fixed-layout message type and the record it holds.

    Attributes:
        msgtype: Full ROS type name, e.g. ``"sensor_msgs/msg/Imu"``.
        record: The sample or record type; built as ``record(t_ns, *fields)`` (with
            ``frame=`` the header's frame id when `frame_from_header`).
        fields: (record attribute, field path in the message), in the record's order;
            the attributes are the stream's columns.
        constants: (field path, value) of the float64 fields that hold a constant
            (the others not in `fields` are zero).
        frame_from_header: The record's ``frame`` is the header's frame id (poses).
    """

    msgtype: str
    record: type[FixedRecord]
    fields: tuple[tuple[str, str], ...]
    constants: tuple[tuple[str, float], ...] = ()
    frame_from_header: bool = False

    @property
    def names(self) -> tuple[str, ...]:
        """Return the record attributes, in column order."""
        return tuple(name for name, _ in self.fields)


def _under(prefix: str, fields: tuple[tuple[str, str], ...]) -> tuple[tuple[str, str], ...]:
    """Return `fields` with their paths under the field `prefix` (a message held inside)."""
    return tuple((name, f"{prefix}.{path}") for name, path in fields)


TWIST = FixedLayout(
    topics.TWIST_TYPE,
    VelocityReference,
    (("surge_mps", "linear.x"), ("sway_mps", "linear.y"), ("yaw_rate_radps", "angular.z")),
)
"""The lab's unstamped Twist (the velocity command): linear.x = u, linear.y = v, angular.z = r."""

WRENCH = FixedLayout(
    topics.WRENCH_TYPE,
    ForceCommand,
    (("surge_n", "force.x"), ("sway_n", "force.y"), ("yaw_nm", "torque.z")),
)
"""The lab's unstamped Wrench (force and per-thruster commands): force.x = X, force.y = Y,
torque.z = N."""

TWIST_STAMPED = FixedLayout(
    topics.TWIST_STAMPED_TYPE, VelocityReference, _under("twist", TWIST.fields)
)
"""TwistStamped: nu_ref, its twist as :data:`TWIST`."""

WRENCH_STAMPED = FixedLayout(
    topics.WRENCH_STAMPED_TYPE, ForceCommand, _under("wrench", WRENCH.fields)
)
"""WrenchStamped: tau, its wrench as :data:`WRENCH`."""

POSE = FixedLayout(
    topics.POSE_TYPE,
    PoseSample,
    (("x_m", "pose.pose.position.x"), ("y_m", "pose.pose.position.y"),
     ("yaw_rad", "pose.pose.orientation")),
    frame_from_header=True,
)  # fmt: skip
"""PoseWithCovarianceStamped: the pose (covariance zero)."""

ODOM = FixedLayout(
    topics.ODOM_TYPE, StateEstimate, POSE.fields + _under("twist.twist", TWIST.fields)
)
"""nav_msgs/Odometry: the estimate, its pose as :data:`POSE`'s in the header's frame, its
twist as :data:`TWIST` in the child's (covariances zero)."""

IMU = FixedLayout(
    topics.IMU_TYPE,
    ImuSample,
    (("accel_x_mps2", "linear_acceleration.x"), ("accel_y_mps2", "linear_acceleration.y"),
     ("yaw_rate_radps", "angular_velocity.z")),
    constants=(("orientation.w", 1.0), ("orientation_covariance[0]", -1.0)),
)  # fmt: skip
"""sensor_msgs/Imu: no orientation (identity, covariance[0] = -1: REP 145)."""

THRUSTERS = FixedLayout(
    ts.THRUSTER_COMMANDS,
    ThrusterCommand,
    (("tunnel", "tunnel"), ("port", "port"), ("starboard", "starboard"),
     ("port_angle_rad", "port_angle"), ("starboard_angle_rad", "starboard_angle")),
)  # fmt: skip
"""hil_msgs/ThrusterCommands: every thruster command and azimuth angle, lossless."""

STAMPED_LAYOUTS = (POSE, IMU, ODOM, TWIST_STAMPED, WRENCH_STAMPED, THRUSTERS)
"""The layouts with a header: read as records and as columns."""

LAYOUTS: dict[str, FixedLayout] = {
    layout.msgtype: layout for layout in (*STAMPED_LAYOUTS, TWIST, WRENCH)
}
"""Message type -> its fixed layout: the table."""

STAMPED_TYPES: frozenset[str] = frozenset(layout.msgtype for layout in STAMPED_LAYOUTS)
"""The message types of :data:`STAMPED_LAYOUTS`."""


@dataclass(frozen=True, slots=True)
class Offsets:
    """Where a layout's fields sit in its message's float64 block (from the typestore).

    Attributes:
        n_values: Length of the float64 block.
        stamped: The message starts with a ``std_msgs/Header``.
        child_frame: A ``child_frame_id`` string follows the header.
        columns: Per field of the layout: (index of its first float64, whether it is a
            yaw held as a quaternion x, y, z, w).
        constants: (index, value) of the constant fields.
    """

    n_values: int
    stamped: bool
    child_frame: bool
    columns: tuple[tuple[int, bool], ...]
    constants: tuple[tuple[int, float], ...]

    def row_fields(self, values: Sequence[float]) -> list[float]:
        """Return the fields of one float64 block (its n_values floats), in layout order."""
        return [
            quaternion_yaw(*values[index : index + 4]) if yaw else values[index]
            for index, yaw in self.columns
        ]


def _leaves(fielddefs: dict[str, Any], typename: str, prefix: str) -> Iterator[tuple[str, str]]:
    """Yield (path, type) of every field of `typename` in CDR order, nested ones first.

    A nested message yields its own path and type name before its fields; a fixed
    array of base types yields each element (``"name[i]"``).
    """
    for name, (node, arg) in fielddefs[typename][1]:
        path = f"{prefix}{name}"
        if node == Nodetype.BASE:
            yield path, arg[0]
        elif node == Nodetype.NAME:
            yield path, arg
            if arg != _HEADER:
                yield from _leaves(fielddefs, arg, f"{path}.")
        elif node == Nodetype.ARRAY and arg[0][0] == Nodetype.BASE:
            yield from ((f"{path}[{i}]", arg[0][1][0]) for i in range(arg[1]))
        else:
            yield path, "sequence"


@functools.cache
def offsets(layout: FixedLayout) -> Offsets:
    """Return the layout's offsets, read from its message definition (cached).

    Raises:
        SchemaError: The message is not a header, a child frame id and float64 fields,
            or a path of the table is not among its fields.
    """
    fielddefs = ts.typestore().fielddefs
    start: dict[str, int] = {}
    kinds: dict[str, str] = {}
    head: list[str] = []
    n = 0
    for path, kind in _leaves(fielddefs, layout.msgtype, ""):
        kinds[path] = kind
        if not n and (path, kind) in (("header", _HEADER), ("child_frame_id", "string")):
            head.append(path)
        elif kind == "float64":
            start[path] = n
            n += 1
        elif kind in fielddefs:
            start[path] = n
        else:
            raise SchemaError(f"{layout.msgtype!r} is not a fixed layout: {path!r} is {kind!r}")
    paths = [path for _, path in layout.fields] + [path for path, _ in layout.constants]
    missing = [path for path in paths if path not in start]
    if missing:
        raise SchemaError(f"{layout.msgtype!r} has no fields {missing!r}")
    columns = tuple((start[path], kinds[path] == _QUATERNION) for _, path in layout.fields)
    constants = tuple((start[path], value) for path, value in layout.constants)
    return Offsets(n, "header" in head, "child_frame_id" in head, columns, constants)


def to_values(layout: FixedLayout, columns: FloatArray) -> FloatArray:
    """Return the float64 blocks of N messages from the records' columns.

    Args:
        layout: The message type's layout.
        columns: The layout's fields (:attr:`FixedLayout.names`), shape (N, k).

    Returns:
        Shape (N, n_values): the fields in place, yaws as quaternions, constants set,
        the rest zero.
    """
    off = offsets(layout)
    out = np.zeros((len(columns), off.n_values))
    for index, value in off.constants:
        out[:, index] = value
    for k, (index, yaw) in enumerate(off.columns):
        if yaw:
            out[:, index : index + 4] = yaw_quaternions(columns[:, k])
        else:
            out[:, index] = columns[:, k]
    return out


def from_values(layout: FixedLayout, values: FloatArray) -> dict[str, FloatArray]:
    """Return the layout's fields of N float64 blocks (N, n_values): name -> (N,) values."""
    out: dict[str, FloatArray] = {}
    for name, (index, yaw) in zip(layout.names, offsets(layout).columns, strict=True):
        if yaw:
            x, y, z, w = (values[:, index + k] for k in range(4))
            out[name] = quaternion_yaws(x, y, z, w)
        else:
            out[name] = values[:, index].copy()
    return out


@functools.cache
def _getters(layout: FixedLayout) -> tuple[tuple[Callable[[Any], Any], bool], ...]:
    return tuple(
        (operator.attrgetter(path), yaw)
        for (_, path), (_, yaw) in zip(layout.fields, offsets(layout).columns, strict=True)
    )


def message_fields(layout: FixedLayout, msg: Any) -> list[float]:
    """Return the layout's fields of a decoded message (rosbags, rclpy: same attributes)."""
    out = []
    for get, yaw in _getters(layout):
        value = get(msg)
        if yaw:
            out.append(quaternion_yaw(float(value.x), float(value.y), float(value.z),
                                      float(value.w)))  # fmt: skip
        else:
            out.append(float(value))
    return out


def build(
    layout: FixedLayout, t_ns: int, fields: Sequence[float], frame: Frame | None = None
) -> FixedRecord:
    """Return the record of a message from its stamp (ns) and fields.

    Args:
        layout: The message type's layout.
        t_ns: The header stamp (ns).
        fields: The layout's fields, in order.
        frame: The header's frame (layouts with `frame_from_header`; else unused).

    Raises:
        SampleError: A value the record refuses (NaN).
    """
    make: Callable[..., FixedRecord] = layout.record
    if layout.frame_from_header and frame is not None:
        return make(t_ns, *fields, frame=frame)
    return make(t_ns, *fields)
