"""Topic names, message types and frame ids of everything hil records, in one place.

Topics follow the lab's ROS 2 interfaces (``/voyager/...``, see VESSEL.md) where
one exists; hil's own streams live under ``/hil/``.
"""

from __future__ import annotations

from hil.bag import typestore as ts

POSE = "/voyager/measurement/pose"
"""Motion-capture pose, geometry_msgs/PoseWithCovarianceStamped."""
IMU = "/voyager/measurement/imu"
"""IMU, sensor_msgs/Imu."""
ODOM = "/voyager/measurement/odom"
"""State estimate, nav_msgs/Odometry."""
VELOCITY_COMMAND = "/voyager/control/velocity/command"
"""Velocity reference nu_ref, geometry_msgs/TwistStamped."""
FORCE_COMMAND = "/voyager/control/force/command"
"""Generalized force tau, geometry_msgs/WrenchStamped."""
THRUSTER_TUNNEL = "/voyager/thruster/tunnel/command"
"""Tunnel thruster command (lab convention: force.x), geometry_msgs/Wrench."""
THRUSTER_PORT = "/voyager/thruster/port/command"
"""Port azimuth command (lab convention: force.x, force.y), geometry_msgs/Wrench."""
THRUSTER_STARBOARD = "/voyager/thruster/starboard/command"
"""Starboard azimuth command (lab convention), geometry_msgs/Wrench."""
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
TWIST_STAMPED_TYPE = "geometry_msgs/msg/TwistStamped"
WRENCH_STAMPED_TYPE = "geometry_msgs/msg/WrenchStamped"
WRENCH_TYPE = "geometry_msgs/msg/Wrench"

TOPIC_TYPES: dict[str, str] = {
    POSE: POSE_TYPE,
    IMU: IMU_TYPE,
    ODOM: ODOM_TYPE,
    VELOCITY_COMMAND: TWIST_STAMPED_TYPE,
    FORCE_COMMAND: WRENCH_STAMPED_TYPE,
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

HIL_TOPICS: frozenset[str] = frozenset(TOPIC_TYPES)
"""The topics that make a log a hil run."""

IMU_FRAME = "voyager/imu_link"
"""Frame id of IMU messages (the lab's)."""
BODY_FRAME = "body"
"""Frame id of body-frame commands and the odometry child frame."""
ARENA_FRAME = "arena"
"""Frame id of arena-frame messages (decisions, layouts, odometry pose)."""
