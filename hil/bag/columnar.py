"""Bulk CDR encoding: many samples of one fixed-layout type into one byte matrix.

The high-rate streams (pose and IMU at 100 Hz, estimate, commands at 20 Hz) have
a fixed CDR layout once the frame ids are fixed, so a batch of N samples becomes
an ``(N, L)`` uint8 matrix filled column-wise with numpy: a constant prefix (CDR
header, frame id, padding), the stamps, and the float64 fields. This is what the
recorder writes at each flush, at about a microsecond per message instead of the
few microseconds of :func:`hil.bag.messages.encode` (which stays the reference:
tests check both give payloads that decode to the same samples).

Layouts and topics follow :mod:`hil.bag.messages`: header stamp = sample time, the
yaw as a quaternion about z, the IMU without orientation, poses in the lab's frame and
on ``/hil/pose`` in the arena, the commands unstamped on the lab's topics and stamped
on ``/hil/...``, the lab's per-thruster Wrench topics plus the lossless
``/hil/thrusters``.
"""

from __future__ import annotations

import functools
import operator
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hil.bag import topics
from hil.bag.errors import RecordValueError
from hil.bag.lab_frame import DEFAULT_LAB_FRAME, LabFrame
from hil.core.arrays import FloatArray
from hil.core.azimuth import azimuth_vectors
from hil.core.clock import NS_PER_S
from hil.core.geometry import yaw_quaternions
from hil.core.records import ForceCommand, StateEstimate
from hil.core.samples import Frame, ImuSample, PoseSample, ThrusterCommand, VelocityReference

_ENCAPSULATION = b"\x00\x01\x00\x00"
_MAX_T_NS = 2**31 * NS_PER_S


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


@dataclass(frozen=True, slots=True)
class _Layout:
    """Byte layout of a payload: constant prefix, stamp offset, float64 offset and count."""

    prefix: bytes
    stamp_offset: int | None
    values_offset: int
    n_values: int

    @property
    def size(self) -> int:
        return self.values_offset + 8 * self.n_values


def _pad(offset: int, align: int) -> int:
    return (-offset) % align


def _string(text: str) -> bytes:
    data = text.encode() + b"\x00"
    return len(data).to_bytes(4, "little") + data


@functools.cache
def _stamped(frame_id: str, n_values: int, child_frame_id: str | None = None) -> _Layout:
    # CDR alignment counts from after the 4-byte encapsulation header.
    body = b"\x00" * 8 + _string(frame_id)
    if child_frame_id is not None:
        body += b"\x00" * _pad(len(body), 4) + _string(child_frame_id)
    body += b"\x00" * _pad(len(body), 8)
    prefix = _ENCAPSULATION + body
    return _Layout(prefix, 4, len(prefix), n_values)


_WRENCH = _Layout(_ENCAPSULATION, None, 4, 6)  # no header: the doubles start the data


def _fill(
    layout: _Layout, t_ns: NDArray[np.int64], values: NDArray[np.float64]
) -> NDArray[np.uint8]:
    n = len(t_ns)
    out = np.empty((n, layout.size), dtype=np.uint8)
    out[:, : layout.values_offset] = np.frombuffer(layout.prefix, dtype=np.uint8)
    if layout.stamp_offset is not None:
        sec, nsec = np.divmod(t_ns, NS_PER_S)
        stamp = np.empty((n, 2), dtype="<u4")
        stamp[:, 0] = sec.astype("<i4").view("<u4")
        stamp[:, 1] = nsec
        out[:, layout.stamp_offset : layout.stamp_offset + 8] = stamp.view(np.uint8)
    out[:, layout.values_offset :] = np.ascontiguousarray(values, dtype="<f8").view(np.uint8)
    return out


def _times(records: Sequence[Any]) -> NDArray[np.int64]:
    t = np.fromiter((r.t_ns for r in records), dtype=np.int64, count=len(records))
    if t.size and (t.min() < 0 or t.max() >= _MAX_T_NS):
        bad = int(t[(t < 0) | (t >= _MAX_T_NS)][0])
        raise RecordValueError(f"time {bad!r} ns does not fit a ROS stamp (int32 seconds >= 0)")
    return t


def _columns(records: Sequence[Any], names: tuple[str, ...]) -> NDArray[np.float64]:
    """Return the named float attributes (at least two), shape (N, len(names))."""
    get = operator.attrgetter(*names)
    return np.array([get(r) for r in records], dtype=np.float64).reshape(len(records), len(names))


def _quaternion_z(values: NDArray[np.float64], yaw: NDArray[np.float64], at: int) -> None:
    values[:, at : at + 4] = yaw_quaternions(yaw)


def _pose_block(topic: str, frame_id: str, t: NDArray[np.int64], poses: FloatArray) -> Block:
    values = np.zeros((len(t), 43))
    values[:, 0:2] = poses[:, 0:2]
    _quaternion_z(values, poses[:, 2], 3)
    return Block(topic, t, _fill(_stamped(frame_id, 43), t, values))


def encode_poses(records: Sequence[PoseSample], lab: LabFrame = DEFAULT_LAB_FRAME) -> list[Block]:
    """Encode poses as PoseWithCovarianceStamped on the lab's topic and on ``/hil/pose``.

    The lab's frame on the lab's topic, the arena on ``/hil/pose``: two blocks per
    frame the records come in.
    """
    blocks = []
    for frame in {r.frame for r in records}:
        group = [r for r in records if r.frame is frame]
        t = _times(group)
        cols = _columns(group, ("x_m", "y_m", "yaw_rad"))
        if frame is Frame.LAB_NED:
            in_lab, in_arena = cols, lab.transform.poses_to_arena(cols)
        else:
            in_lab, in_arena = lab.transform.poses_to_lab(cols), cols
        blocks.append(_pose_block(topics.POSE, lab.frame_id, t, in_lab))
        blocks.append(_pose_block(topics.HIL_POSE, topics.ARENA_FRAME, t, in_arena))
    return blocks


def encode_imus(records: Sequence[ImuSample]) -> list[Block]:
    """Encode IMU samples as sensor_msgs/Imu (no orientation: covariance[0] = -1)."""
    t = _times(records)
    cols = _columns(records, ("accel_x_mps2", "accel_y_mps2", "yaw_rate_radps"))
    values = np.zeros((len(records), 37))
    values[:, 3] = 1.0  # identity orientation, flagged unknown below
    values[:, 4] = -1.0
    values[:, 15] = cols[:, 2]  # angular_velocity.z
    values[:, 25] = cols[:, 0]  # linear_acceleration.x
    values[:, 26] = cols[:, 1]
    return [Block(topics.IMU, t, _fill(_stamped(topics.IMU_FRAME, 37), t, values))]


def encode_estimates(records: Sequence[StateEstimate]) -> list[Block]:
    """Encode estimates as nav_msgs/Odometry (pose in the arena, twist in the body frame)."""
    t = _times(records)
    names = ("x_m", "y_m", "yaw_rad", "surge_mps", "sway_mps", "yaw_rate_radps")
    cols = _columns(records, names)
    values = np.zeros((len(records), 85))
    values[:, 0:2] = cols[:, 0:2]
    _quaternion_z(values, cols[:, 2], 3)
    values[:, 43:45] = cols[:, 3:5]  # twist.linear.x, .y
    values[:, 48] = cols[:, 5]  # twist.angular.z
    layout = _stamped(topics.ARENA_FRAME, 85, topics.BODY_FRAME)
    return [Block(topics.HIL_ODOM, t, _fill(layout, t, values))]


def _body_six(
    topics_: tuple[str, str], records: Sequence[Any], names: tuple[str, str, str]
) -> list[Block]:
    """Unstamped on the lab's topic (Twist, Wrench), stamped on hil's (first, second)."""
    t = _times(records)
    cols = _columns(records, names)
    values = np.zeros((len(records), 6))
    values[:, 0:2] = cols[:, 0:2]
    values[:, 5] = cols[:, 2]
    return [
        Block(topics_[0], t, _fill(_WRENCH, t, values)),
        Block(topics_[1], t, _fill(_stamped(topics.BODY_FRAME, 6), t, values)),
    ]


def encode_velocity_references(records: Sequence[VelocityReference]) -> list[Block]:
    """Encode nu_ref as the lab's Twist and TwistStamped on /hil.

    linear.x = u, linear.y = v, angular.z = r.
    """
    return _body_six(
        (topics.VELOCITY_COMMAND, topics.HIL_VELOCITY_COMMAND),
        records,
        ("surge_mps", "sway_mps", "yaw_rate_radps"),
    )


def encode_forces(records: Sequence[ForceCommand]) -> list[Block]:
    """Encode tau as the lab's Wrench and WrenchStamped on /hil.

    force.x = X, force.y = Y, torque.z = N.
    """
    return _body_six(
        (topics.FORCE_COMMAND, topics.HIL_FORCE_COMMAND), records, ("surge_n", "sway_n", "yaw_nm")
    )


def encode_thruster_commands(records: Sequence[ThrusterCommand]) -> list[Block]:
    """Encode thruster commands on the lab's three Wrench topics and /hil/thrusters."""
    t = _times(records)
    names = ("tunnel", "port", "starboard", "port_angle_rad", "starboard_angle_rad")
    cols = _columns(records, names)
    n = len(records)
    tunnel = np.zeros((n, 6))
    tunnel[:, 0] = cols[:, 0]
    port = np.zeros((n, 6))
    port[:, :2] = azimuth_vectors(cols[:, 1], cols[:, 3])
    starboard = np.zeros((n, 6))
    starboard[:, :2] = azimuth_vectors(cols[:, 2], cols[:, 4])
    return [
        Block(topics.THRUSTER_TUNNEL, t, _fill(_WRENCH, t, tunnel)),
        Block(topics.THRUSTER_PORT, t, _fill(_WRENCH, t, port)),
        Block(topics.THRUSTER_STARBOARD, t, _fill(_WRENCH, t, starboard)),
        Block(topics.THRUSTERS, t, _fill(_stamped(topics.BODY_FRAME, 5), t, cols)),
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
