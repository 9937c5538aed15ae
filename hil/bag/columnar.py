"""Bulk CDR encoding: many samples of one fixed-layout type into one byte matrix.

The high-rate streams (pose and IMU at 100 Hz, estimate, commands at 20 Hz) have
a fixed CDR layout once the frame ids are fixed, so a batch of N samples becomes
an ``(N, L)`` uint8 matrix filled column-wise with numpy: a constant prefix (CDR
header, frame id, padding), the stamps, and the float64 fields. This is what the
recorder writes at each flush, at about a microsecond per message instead of the
few microseconds of :func:`hil.bag.messages.encode` (which stays the reference:
tests check both give payloads that decode to the same samples).

The fields and their places are the field table's (:mod:`hil.bag.field_table`), the
bytes :mod:`hil.bag.cdr`'s. Where each goes (:mod:`hil.bag.topics`): poses in the lab's
frame on the lab's topic and on ``/hil/pose`` in the arena, the IMU as received, the
estimate on ``/hil/odom``, the commands unstamped on the lab's topics and stamped on
``/hil/...``, the lab's per-thruster Wrench topics (each azimuth as the vector of
:mod:`hil.core.azimuth`) plus the lossless ``/hil/thrusters``.
"""

from __future__ import annotations

import functools
import operator
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hil.bag import cdr, topics
from hil.bag import field_table as ft
from hil.bag.lab_frame import DEFAULT_LAB_FRAME, LabFrame
from hil.core.arrays import FloatArray
from hil.core.azimuth import azimuth_vectors
from hil.core.records import ForceCommand, StateEstimate
from hil.core.samples import Frame, ImuSample, PoseSample, ThrusterCommand, VelocityReference


@dataclass(frozen=True, slots=True)
class Block:
    """N messages of one topic.

    Attributes:
        topic: Topic name.
        t_ns: Log times (ns), shape (N,), int64.
        payloads: CDR payloads, shape (N, L), uint8, one row per message.
    """

    topic: str
    t_ns: NDArray[np.int64]
    payloads: NDArray[np.uint8]


@functools.cache
def _prefix(frame_id: str | None, child_frame_id: str | None) -> NDArray[np.uint8]:
    return np.frombuffer(cdr.prefix(frame_id, child_frame_id), dtype=np.uint8)


def _block(
    topic: str,
    layout: ft.FixedLayout,
    t_ns: NDArray[np.int64],
    columns: FloatArray,
    frame_id: str = "",
    child_frame_id: str | None = None,
) -> Block:
    """Encode N messages of `layout` from the records' columns (N, k) and times (N,) in ns.

    `frame_id` (and `child_frame_id`) go into the header of a stamped layout.
    """
    off = ft.offsets(layout)
    prefix = _prefix(frame_id if off.stamped else None, child_frame_id)
    out = np.empty((len(t_ns), len(prefix) + 8 * off.n_values), dtype=np.uint8)
    out[:, : len(prefix)] = prefix
    if off.stamped:
        out[:, cdr.STAMP_OFFSET : cdr.STAMP_OFFSET + 8] = cdr.stamp_bytes(t_ns)
    values = ft.to_values(layout, columns)
    out[:, len(prefix) :] = np.ascontiguousarray(values, dtype="<f8").view(np.uint8)
    return Block(topic, t_ns, out)


def _times(records: Sequence[Any]) -> NDArray[np.int64]:
    t = np.fromiter((r.t_ns for r in records), dtype=np.int64, count=len(records))
    cdr.check_stamps(t)
    return t


def _columns(records: Sequence[Any], names: tuple[str, ...]) -> NDArray[np.float64]:
    """Return the named float attributes (at least two), shape (N, len(names))."""
    get = operator.attrgetter(*names)
    return np.array([get(r) for r in records], dtype=np.float64).reshape(len(records), len(names))


def encode_poses(records: Sequence[PoseSample], lab: LabFrame = DEFAULT_LAB_FRAME) -> list[Block]:
    """Encode poses as PoseWithCovarianceStamped on the lab's topic and on ``/hil/pose``.

    The lab's frame on the lab's topic, the arena on ``/hil/pose``: two blocks per
    frame the records come in.
    """
    blocks = []
    for frame in {r.frame for r in records}:
        group = [r for r in records if r.frame is frame]
        t = _times(group)
        cols = _columns(group, ft.POSE.names)
        if frame is Frame.LAB_NED:
            in_lab, in_arena = cols, lab.transform.poses_to_arena(cols)
        else:
            in_lab, in_arena = lab.transform.poses_to_lab(cols), cols
        blocks.append(_block(topics.POSE, ft.POSE, t, in_lab, lab.frame_id))
        blocks.append(_block(topics.HIL_POSE, ft.POSE, t, in_arena, topics.ARENA_FRAME))
    return blocks


def encode_imus(records: Sequence[ImuSample]) -> list[Block]:
    """Encode IMU samples as sensor_msgs/Imu (no orientation: covariance[0] = -1)."""
    cols = _columns(records, ft.IMU.names)
    return [_block(topics.IMU, ft.IMU, _times(records), cols, topics.IMU_FRAME)]


def encode_estimates(records: Sequence[StateEstimate]) -> list[Block]:
    """Encode estimates as nav_msgs/Odometry (pose in the arena, twist in the body frame)."""
    cols = _columns(records, ft.ODOM.names)
    t = _times(records)
    return [_block(topics.HIL_ODOM, ft.ODOM, t, cols, topics.ARENA_FRAME, topics.BODY_FRAME)]


def _body_three(
    topics_: tuple[str, str], records: Sequence[Any], layouts: tuple[ft.FixedLayout, ...]
) -> list[Block]:
    """Unstamped on the lab's topic (Twist, Wrench), stamped on hil's (first, second)."""
    t = _times(records)
    cols = _columns(records, layouts[0].names)
    return [
        _block(topics_[0], layouts[0], t, cols),
        _block(topics_[1], layouts[1], t, cols, topics.BODY_FRAME),
    ]


def encode_velocity_references(records: Sequence[VelocityReference]) -> list[Block]:
    """Encode nu_ref as the lab's Twist and TwistStamped on /hil.

    linear.x = u, linear.y = v, angular.z = r.
    """
    return _body_three(
        (topics.VELOCITY_COMMAND, topics.HIL_VELOCITY_COMMAND),
        records,
        (ft.TWIST, ft.TWIST_STAMPED),
    )


def encode_forces(records: Sequence[ForceCommand]) -> list[Block]:
    """Encode tau as the lab's Wrench and WrenchStamped on /hil.

    force.x = X, force.y = Y, torque.z = N.
    """
    return _body_three(
        (topics.FORCE_COMMAND, topics.HIL_FORCE_COMMAND), records, (ft.WRENCH, ft.WRENCH_STAMPED)
    )


def encode_thruster_commands(records: Sequence[ThrusterCommand]) -> list[Block]:
    """Encode thruster commands on the lab's three Wrench topics and /hil/thrusters.

    Each lab Wrench holds its thrust vector in force.x, force.y (torque zero): the
    tunnel's command in force.x, each azimuth's as :func:`hil.core.azimuth.azimuth_vectors`.
    """
    t = _times(records)
    cols = _columns(records, ft.THRUSTERS.names)
    zero = np.zeros((len(records), 1))
    vectors = (
        np.column_stack([cols[:, 0], zero[:, 0]]),
        azimuth_vectors(cols[:, 1], cols[:, 3]),
        azimuth_vectors(cols[:, 2], cols[:, 4]),
    )
    lab = (topics.THRUSTER_TUNNEL, topics.THRUSTER_PORT, topics.THRUSTER_STARBOARD)
    wrenches = zip(lab, vectors, strict=True)
    return [
        *(_block(topic, ft.WRENCH, t, np.hstack([v, zero])) for topic, v in wrenches),
        _block(topics.THRUSTERS, ft.THRUSTERS, t, cols, topics.BODY_FRAME),
    ]


BULK_ENCODERS: dict[type, Callable[[Sequence[Any]], list[Block]]] = {
    PoseSample: encode_poses,
    ImuSample: encode_imus,
    StateEstimate: encode_estimates,
    VelocityReference: encode_velocity_references,
    ForceCommand: encode_forces,
    ThrusterCommand: encode_thruster_commands,
}
"""Record type -> bulk encoder, for the fixed-layout types."""
