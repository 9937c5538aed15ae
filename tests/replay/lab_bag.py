"""A bag as the lab records it: only the /voyager/... topics, written with rosbags.

:func:`write_lab_bag` converts one of hil's logs: every ``/hil/...`` topic and the
metadata's ``custom_data`` are dropped, and what is kept is re-typed the way the
lab's stack publishes it (VESSEL.md): the pose in the lab's ``world_ned`` frame,
the velocity command as an unstamped ``geometry_msgs/Twist``, the force command as
an unstamped ``geometry_msgs/Wrench``, the per-thruster ``Wrench`` commands as they
are. With ``native=False`` hil's own types are kept (only the topics are dropped).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any

from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from hil.adapters.frames import ArenaTransform, quaternion_from_yaw, yaw_from_quaternion
from hil.bag import topics
from hil.core.samples import Frame, PoseSample

TWIST = "geometry_msgs/msg/Twist"
WRENCH = "geometry_msgs/msg/Wrench"

LAB_TOPICS = (
    topics.POSE,
    topics.IMU,
    topics.ODOM,
    topics.VELOCITY_COMMAND,
    topics.FORCE_COMMAND,
    topics.THRUSTER_TUNNEL,
    topics.THRUSTER_PORT,
    topics.THRUSTER_STARBOARD,
)


def _to_lab(msg: Any, transform: ArenaTransform) -> None:
    """Express the arena pose of `msg` (a pose or odometry message) in the lab's frame."""
    p = msg.pose.pose
    q = p.orientation
    yaw = yaw_from_quaternion(q.x, q.y, q.z, q.w)
    lab = transform.to_lab(PoseSample(0, p.position.x, p.position.y, yaw, Frame.ARENA))
    p.position.x, p.position.y = lab.x_m, lab.y_m
    q.x, q.y, q.z, q.w = quaternion_from_yaw(lab.yaw_rad)
    msg.header.frame_id = "world_ned"


def _convert(topic: str, msg: Any, native: bool, transform: ArenaTransform) -> tuple[str, Any]:
    """Return (type, message) as the lab publishes `msg` of hil's `topic`."""
    if not native:
        return "", msg
    if topic == topics.POSE:
        _to_lab(msg, transform)
        return topics.POSE_TYPE, msg
    if topic == topics.ODOM:
        _to_lab(msg, transform)
        return topics.ODOM_TYPE, msg
    if topic == topics.VELOCITY_COMMAND:
        return TWIST, msg.twist
    if topic == topics.FORCE_COMMAND:
        return WRENCH, msg.wrench
    return "", msg


def write_lab_bag(
    source: Path,
    dest: Path,
    *,
    native: bool = True,
    drop: Collection[str] = (),
    transform: ArenaTransform | None = None,
    rename: Mapping[str, str] | None = None,
) -> Path:
    """Write the lab's topics of hil log `source` to a new MCAP bag `dest`; return `dest`.

    Args:
        source: A hil log (bag directory).
        dest: The bag directory to create (must not exist).
        native: Re-type as the lab publishes (see the module docstring).
        drop: Lab topics to leave out as well (e.g. the pose, the odometry).
        transform: Where the arena lies in the lab (poses are written in the lab's
            frame through its inverse); None: the identity.
        rename: Topic names to write instead of the lab's defaults (a vessel config's).
    """
    rename = rename or {}
    transform = transform or ArenaTransform()
    store = get_typestore(Stores.ROS2_JAZZY)
    keep = [t for t in LAB_TOPICS if t not in drop]
    with AnyReader([source], default_typestore=store) as reader:
        connections = [c for c in reader.connections if c.topic in keep]
        with Writer(dest, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            out: dict[str, Any] = {}
            for conn, t_ns, data in reader.messages(connections=connections):
                msg = reader.deserialize(data, conn.msgtype)
                msgtype, converted = _convert(conn.topic, msg, native, transform)
                msgtype = msgtype or conn.msgtype
                if conn.topic not in out:
                    name = rename.get(conn.topic, conn.topic)
                    out[conn.topic] = writer.add_connection(name, msgtype, typestore=store)
                writer.write(out[conn.topic], t_ns, store.serialize_cdr(converted, msgtype))
    return dest
