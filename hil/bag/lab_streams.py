"""The lab's own topics as hil's streams: a bag the lab recorded, without hil's topics.

A bag recorded on the tank with ``ros2 bag record`` holds the lab's ``/voyager/...``
topics only (VESSEL.md): the motion-capture pose in the lab's ``world_ned`` frame,
the IMU, perhaps the lab EKF's odometry, the velocity command as an unstamped
``geometry_msgs/Twist``, the force command as an unstamped ``geometry_msgs/Wrench``
and the three per-thruster ``Wrench`` commands. :class:`LabTopics` says where each
is (the vessel config's topic names may differ) and how a lab pose maps to the
arena; :func:`hil.bag.run_data.load_run` reads such a bag with it.

What an unstamped message lacks, its log time stands in for (the time the recorder
received it). The per-thruster commands hold each azimuth as ``c (cos a, sin a)``
(force.x, force.y), which loses the sign of ``c``: they are read back as magnitude
``|c|`` and angle ``atan2(force.y, force.x)``, the same thrust vector.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hil.bag import field_table as ft
from hil.bag import topics
from hil.bag.storage import RawMessage
from hil.core.arrays import FloatArray, IntArray
from hil.core.azimuth import azimuth_commands
from hil.core.samples import ThrusterCommand
from hil.core.timeline import in_force

TWIST_TYPE = topics.TWIST_TYPE
"""The lab's velocity command (unstamped)."""
WRENCH_TYPE = topics.WRENCH_TYPE
"""The lab's force and per-thruster commands (unstamped)."""
UNSTAMPED_TYPES = frozenset({TWIST_TYPE, WRENCH_TYPE})
"""Types read at their log time."""
LAB_POSE_FRAME = "world_ned"
"""Frame id of the lab's motion-capture poses."""

PoseMap = Callable[[FloatArray], FloatArray]
"""Lab poses (N, 3) (north m, east m, yaw rad) to arena poses (N, 3) (x m, y m, psi rad)."""


@dataclass(frozen=True, slots=True)
class LabTopics:
    """Where the lab's streams are in a bag, and how its poses map to the arena.

    Attributes:
        pose: Motion-capture pose (PoseWithCovarianceStamped).
        imu: IMU (sensor_msgs/Imu).
        odom: The lab's state estimate (nav_msgs/Odometry); may be absent.
        velocity_command: Velocity reference (Twist or TwistStamped); may be absent.
        force_command: Force command (Wrench or WrenchStamped); may be absent.
        tunnel: Tunnel thruster command (Wrench, force.x).
        port: Port azimuth command (Wrench, force.x and force.y).
        starboard: Starboard azimuth command (Wrench).
        pose_to_arena: Maps poses in ``world_ned`` to the arena; None leaves such
            poses refused (:class:`~hil.bag.errors.FrameError`).
        transform_note: One line on the mapping used, for reports.
    """

    pose: str = topics.POSE
    imu: str = topics.IMU
    odom: str = topics.ODOM
    velocity_command: str = topics.VELOCITY_COMMAND
    force_command: str = topics.FORCE_COMMAND
    tunnel: str = topics.THRUSTER_TUNNEL
    port: str = topics.THRUSTER_PORT
    starboard: str = topics.THRUSTER_STARBOARD
    pose_to_arena: PoseMap | None = None
    transform_note: str = ""

    def renames(self) -> dict[str, str]:
        """Return bag topic -> hil's topic of the same stream (only those that differ kept too)."""
        return {
            self.pose: topics.POSE,
            self.imu: topics.IMU,
            self.odom: topics.ODOM,
            self.velocity_command: topics.VELOCITY_COMMAND,
            self.force_command: topics.FORCE_COMMAND,
            self.tunnel: topics.THRUSTER_TUNNEL,
            self.port: topics.THRUSTER_PORT,
            self.starboard: topics.THRUSTER_STARBOARD,
        }


def unstamped_values(
    raws: Sequence[RawMessage], decode: Callable[[RawMessage], Any], msgtype: str
) -> tuple[IntArray, FloatArray, list[tuple[RawMessage, str]]]:
    """Decode Twist or Wrench messages at their log time.

    Args:
        raws: The topic's messages in log-time order.
        decode: Raw message -> rosbags message object.
        msgtype: :data:`TWIST_TYPE` or :data:`WRENCH_TYPE`.

    Returns:
        Log times (N,), values (N, 3) (the field table's, :data:`hil.bag.field_table.TWIST`:
        linear.x, linear.y, angular.z; :data:`~hil.bag.field_table.WRENCH`: force.x,
        force.y, torque.z) and the messages left out with why (one that does not decode
        or holds a non-finite value).
    """
    layout = ft.LAYOUTS[msgtype]
    t_ns: list[int] = []
    rows: list[tuple[float, ...]] = []
    bad: list[tuple[RawMessage, str]] = []
    for raw in raws:
        try:
            row = tuple(ft.message_fields(layout, decode(raw)))
        except ValueError as err:
            bad.append((raw, str(err)))
            continue
        if not all(math.isfinite(v) for v in row):
            bad.append((raw, f"{msgtype} on {raw.topic!r} has non-finite values {row!r}"))
            continue
        t_ns.append(raw.t_ns)
        rows.append(row)
    return np.array(t_ns, dtype=np.int64), np.array(rows, dtype=np.float64).reshape(-1, 3), bad


def _held(t_ns: IntArray, src_t: IntArray, src: FloatArray) -> FloatArray:
    """Return `src` (M, k) held at `t_ns` (N,): the newest at or before, zeros before the first."""
    out = np.zeros((len(t_ns), src.shape[1]))
    if not len(src_t):
        return out
    k = in_force(src_t, t_ns)
    has = k >= 0
    out[has] = src[k[has]]
    return out


def thrusters_from_wrenches(
    tunnel: tuple[IntArray, FloatArray],
    port: tuple[IntArray, FloatArray],
    starboard: tuple[IntArray, FloatArray],
) -> tuple[IntArray, FloatArray]:
    """Combine the three per-thruster Wrench streams into hil's thruster columns.

    Args:
        tunnel: Tunnel commands: log times (N,), (force.x, force.y, torque.z) (N, 3).
        port: Port azimuth commands, the same layout.
        starboard: Starboard azimuth commands, the same layout.

    Returns:
        Times (union of the three, ascending) and (N, 5) columns: tunnel, port,
        starboard in [-1, 1], port and starboard angles (rad); each thruster's newest
        command held (zero before its first). The azimuths by the decode rule of
        :mod:`hil.core.azimuth`: each pod keeps the side of its angle before (its
        reference angle before the first), as the lab's driver turns it.
    """
    t_ns = np.unique(np.concatenate([tunnel[0], port[0], starboard[0]]))
    tun = _held(t_ns, *tunnel)
    prt = _held(t_ns, *port)
    stb = _held(t_ns, *starboard)
    rest = ThrusterCommand.zero(0)
    port_thrust, port_angle = azimuth_commands(prt[:, 0], prt[:, 1], rest.port_angle_rad)
    stbd_thrust, stbd_angle = azimuth_commands(stb[:, 0], stb[:, 1], rest.starboard_angle_rad)
    values = np.column_stack([tun[:, 0], port_thrust, stbd_thrust, port_angle, stbd_angle])
    return t_ns.astype(np.int64), values
