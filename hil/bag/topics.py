"""Topic names, message types and frame ids of everything hil records, in one place.

The lab's topics (``/voyager/...``, see VESSEL.md) hold what the lab's stack would
have on them, in the lab's types and frames: the mocap pose in ``world_ned`` as
received (in simulation: the simulated pose mapped back through the configured
transform), the IMU as received, the unstamped ``Twist`` velocity and ``Wrench``
force commands and the per-thruster ``Wrench`` commands as sent. hil's own derived
streams live under ``/hil/``: the arena-frame pose, its estimate, the stamped
commands, the lossless thruster commands, decisions, layouts, events, controllers
and the QTM 6D samples. ``/tf_static`` holds the transforms between the frames.

Logs of hil format 2 (before 3) held hil's arena pose, estimate and stamped commands
on the lab's names; :data:`STREAM_TOPICS` says where each stream is read in either.
"""

from __future__ import annotations

from hil.bag import typestore as ts

POSE = "/voyager/measurement/pose"
"""Motion-capture pose as received, geometry_msgs/PoseWithCovarianceStamped in the lab's
frame (hil format 2: the arena pose). Also the key of the pose stream in a run."""
IMU = "/voyager/measurement/imu"
"""IMU, sensor_msgs/Imu."""
ODOM = "/voyager/measurement/odom"
"""The lab EKF's state estimate, nav_msgs/Odometry (hil format 2: hil's estimate); the key
of the estimate stream in a run."""
VELOCITY_COMMAND = "/voyager/control/velocity/command"
"""Velocity reference nu_ref as the lab sends it, geometry_msgs/Twist (hil format 2:
TwistStamped); the key of the reference stream in a run."""
FORCE_COMMAND = "/voyager/control/force/command"
"""Generalized force tau as the lab sends it, geometry_msgs/Wrench (hil format 2:
WrenchStamped); the key of the force stream in a run."""
THRUSTER_TUNNEL = "/voyager/thruster/tunnel/command"
"""Tunnel thruster command (lab convention: force.x), geometry_msgs/Wrench."""
THRUSTER_PORT = "/voyager/thruster/port/command"
"""Port azimuth command (lab convention: force.x, force.y), geometry_msgs/Wrench."""
THRUSTER_STARBOARD = "/voyager/thruster/starboard/command"
"""Starboard azimuth command (lab convention), geometry_msgs/Wrench."""
HIL_POSE = "/hil/pose"
"""The pose hil's stack used, in the arena, geometry_msgs/PoseWithCovarianceStamped."""
HIL_ODOM = "/hil/odom"
"""hil's state estimate, nav_msgs/Odometry (pose in the arena, twist in the body frame)."""
HIL_VELOCITY_COMMAND = "/hil/velocity/command"
"""Velocity reference nu_ref, geometry_msgs/TwistStamped in the body frame."""
HIL_FORCE_COMMAND = "/hil/force/command"
"""Generalized force tau, geometry_msgs/WrenchStamped in the body frame."""
QTM_6D = "/hil/qtm/6d"
"""QTM 6D frames of the vessel's rigid body as received, hil_msgs/Qtm6D."""
TF_STATIC = "/tf_static"
"""The static transforms ``world_ned -> arena`` and ``mocap body -> body``,
tf2_msgs/TFMessage (one message, at the run's first record)."""
THRUSTERS = "/hil/thrusters"
"""All thruster commands and azimuth angles, lossless, hil_msgs/ThrusterCommands."""
DECISION = "/hil/decision"
"""Symbolic controller decisions, hil_msgs/Decision."""
OBSTACLES = "/hil/obstacles"
"""Obstacle layouts, hil_msgs/ObstacleLayout."""
EVENTS = "/hil/events"
"""Runtime events and faults, hil_msgs/Event."""
CONTROLLERS = "/hil/controllers"
"""Each controller taken from the re-synthesis (version, solve time, source),
hil_msgs/ControllerReady."""

POSE_TYPE = "geometry_msgs/msg/PoseWithCovarianceStamped"
IMU_TYPE = "sensor_msgs/msg/Imu"
ODOM_TYPE = "nav_msgs/msg/Odometry"
TWIST_TYPE = "geometry_msgs/msg/Twist"
TWIST_STAMPED_TYPE = "geometry_msgs/msg/TwistStamped"
WRENCH_STAMPED_TYPE = "geometry_msgs/msg/WrenchStamped"
WRENCH_TYPE = "geometry_msgs/msg/Wrench"
TF_TYPE = "tf2_msgs/msg/TFMessage"

TOPIC_TYPES: dict[str, str] = {
    POSE: POSE_TYPE,
    IMU: IMU_TYPE,
    VELOCITY_COMMAND: TWIST_TYPE,
    FORCE_COMMAND: WRENCH_TYPE,
    HIL_POSE: POSE_TYPE,
    HIL_ODOM: ODOM_TYPE,
    HIL_VELOCITY_COMMAND: TWIST_STAMPED_TYPE,
    HIL_FORCE_COMMAND: WRENCH_STAMPED_TYPE,
    QTM_6D: ts.QTM_6D,
    TF_STATIC: TF_TYPE,
    THRUSTER_TUNNEL: WRENCH_TYPE,
    THRUSTER_PORT: WRENCH_TYPE,
    THRUSTER_STARBOARD: WRENCH_TYPE,
    THRUSTERS: ts.THRUSTER_COMMANDS,
    DECISION: ts.DECISION,
    OBSTACLES: ts.OBSTACLE_LAYOUT,
    EVENTS: ts.EVENT,
    CONTROLLERS: ts.CONTROLLER_READY,
}
"""Every topic hil records and its message type."""

STREAM_TOPICS: dict[str, str] = {
    HIL_POSE: POSE,
    HIL_ODOM: ODOM,
    HIL_VELOCITY_COMMAND: VELOCITY_COMMAND,
    HIL_FORCE_COMMAND: FORCE_COMMAND,
}
"""hil's own topic -> the stream it holds (keyed by the lab's name, as in hil format 2).

A bag with one of these topics is read from it, and the lab's topic of that stream
(the pose as received, the unstamped command) is left beside it; a bag without them
(hil format 2, or the lab's own bag) is read from the lab's names."""

STREAM_TOPICS_BY_STREAM: dict[str, str] = {v: k for k, v in STREAM_TOPICS.items()}
"""The stream (the lab's name) -> hil's own topic that holds it in hil format 3."""

HIL_TOPICS: frozenset[str] = frozenset(TOPIC_TYPES) | {ODOM}
"""The topics that make a log a hil run (with the estimate's name of hil format 2)."""

IMU_FRAME = "voyager/imu_link"
"""Frame id of IMU messages (the lab's)."""
BODY_FRAME = "body"
"""Frame id of body-frame commands and the odometry child frame."""
ARENA_FRAME = "arena"
"""Frame id of arena-frame messages (decisions, layouts, odometry pose)."""
LAB_FRAME = "world_ned"
"""Frame id of the lab's world (mocap poses), the parent of ``arena`` on ``/tf_static``."""
MOCAP_BODY_FRAME = "mocap_body"
"""Frame id of the mocap rigid body, the parent of ``body`` on ``/tf_static``."""
QTM_FRAME = "qtm"
"""Frame id of the QTM 6D samples (QTM's global axes, the lab's NED world)."""
