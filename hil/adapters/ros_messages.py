"""Conversions between the lab's ROS messages and samples (VESSEL.md).

Plain functions over message attributes, so they serve rclpy messages and `rosbags`
messages alike; :mod:`hil.adapters.ros` re-exports them.
"""

from __future__ import annotations

from typing import Any

from hil.adapters.frames import ArenaTransform, quaternion_from_yaw, yaw_from_quaternion
from hil.core.azimuth import azimuth_command, azimuth_vector
from hil.core.clock import fill_stamp, stamp_to_ns
from hil.core.samples import Frame, ImuSample, PoseSample, ThrusterCommand


def pose_from_msg(msg: Any, transform: ArenaTransform) -> PoseSample:
    """Convert a PoseWithCovarianceStamped in the lab's NED world to an arena pose.

    Raises:
        SampleError: On non-finite values or a non-unit orientation.
    """
    pose = msg.pose.pose
    q = pose.orientation
    yaw = yaw_from_quaternion(float(q.x), float(q.y), float(q.z), float(q.w))
    lab = PoseSample(
        stamp_to_ns(msg.header.stamp),
        float(pose.position.x),
        float(pose.position.y),
        yaw,
        Frame.LAB_NED,
    )
    return transform.to_arena(lab)


def fill_pose_msg(
    msg: Any, pose: PoseSample, transform: ArenaTransform, frame_id: str = "world_ned"
) -> None:
    """Fill a PoseWithCovarianceStamped with an arena pose, expressed in the lab frame."""
    lab = transform.to_lab(pose)
    fill_stamp(msg.header.stamp, lab.t_ns)
    msg.header.frame_id = frame_id
    msg.pose.pose.position.x = lab.x_m
    msg.pose.pose.position.y = lab.y_m
    msg.pose.pose.position.z = 0.0
    o = msg.pose.pose.orientation
    o.x, o.y, o.z, o.w = quaternion_from_yaw(lab.yaw_rad)


def imu_from_msg(msg: Any) -> ImuSample:
    """Convert a sensor_msgs/Imu to an IMU sample (planar specific force and yaw rate)."""
    return ImuSample(
        stamp_to_ns(msg.header.stamp),
        float(msg.linear_acceleration.x),
        float(msg.linear_acceleration.y),
        float(msg.angular_velocity.z),
    )


def fill_imu_msg(msg: Any, imu: ImuSample, frame_id: str = "voyager/imu_link") -> None:
    """Fill a sensor_msgs/Imu from an IMU sample; orientation marked as unknown."""
    fill_stamp(msg.header.stamp, imu.t_ns)
    msg.header.frame_id = frame_id
    msg.linear_acceleration.x = imu.accel_x_mps2
    msg.linear_acceleration.y = imu.accel_y_mps2
    msg.angular_velocity.z = imu.yaw_rate_radps
    # REP 145: covariance[0] = -1 says the orientation is not provided.
    msg.orientation_covariance[0] = -1.0


def thruster_wrench_components(command: ThrusterCommand) -> dict[str, tuple[float, float]]:
    """Return the normalized (force.x, force.y) the lab's driver expects per thruster.

    The tunnel uses force.x only; each azimuth takes its thrust as a vector in the
    body frame, so the angle is carried by the direction of (force.x, force.y).
    """
    return {
        "tunnel": (command.tunnel, 0.0),
        "port": azimuth_vector(command.port, command.port_angle_rad),
        "starboard": azimuth_vector(command.starboard, command.starboard_angle_rad),
    }


def thruster_command_from_components(
    t_ns: int,
    tunnel_x: float,
    port: tuple[float, float],
    starboard: tuple[float, float],
    previous: ThrusterCommand | None = None,
) -> ThrusterCommand:
    """Rebuild a command from the lab's wrench components (inverse of the above).

    The decode rule of :mod:`hil.core.azimuth`: each pod keeps the side of its angle in
    `previous` (without one, of its reference angle) and reverses the propeller when
    the vector points behind it; a zero vector keeps the angle.
    """
    fallback = previous or ThrusterCommand.zero(t_ns)
    port_thrust, port_angle = azimuth_command(*port, fallback.port_angle_rad)
    stbd_thrust, stbd_angle = azimuth_command(*starboard, fallback.starboard_angle_rad)
    return ThrusterCommand(
        t_ns, max(-1.0, min(1.0, tunnel_x)), port_thrust, stbd_thrust, port_angle, stbd_angle
    )
