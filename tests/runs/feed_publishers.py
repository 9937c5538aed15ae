"""A stand-in for the lab's mocap and IMU drivers: a plain rclpy node, misconfigurable.

Publishes the lab's pose and IMU topics from a thread of its own (in its own rclpy
context), with the faults drivers have: best-effort QoS, another frame id, 10 Hz stamped
on receipt, NaN while the body is occluded. Poses put the vessel at a winning start of the
coarse scenario (the arena transform is the identity).

Run as a script for a manual check: ``python -m tests.runs.feed_publishers --help``.
"""

from __future__ import annotations

import argparse
import math
import os
import threading
import time
from dataclasses import dataclass
from typing import Any

NS_PER_S = 1_000_000_000


@dataclass(frozen=True)
class FeedFaults:
    """How the stand-in publishes.

    Attributes:
        best_effort: Publish with BEST_EFFORT reliability (sensor-data QoS).
        frame_id: The poses' header.frame_id.
        rate_hz: Publication rate (Hz).
        delay_s: How long before publication each sample is stamped (s): 0.01 is a
            capture stamp 10 ms old; 0 stamps on receipt.
        nan: Publish NaN positions (the rigid body occluded).
        nan_every: With `nan` false, make every n-th pose NaN (0: none).
        pose: Arena pose (x m, y m, yaw rad) to report.
    """

    best_effort: bool = False
    frame_id: str = "world_ned"
    rate_hz: float = 100.0
    delay_s: float = 0.01
    nan: bool = False
    nan_every: int = 0
    pose: tuple[float, float, float] = (0.0, -1.0, math.pi)


class FeedPublisher:
    """Publishes pose and IMU on `domain_id` until :meth:`close` (a context manager)."""

    def __init__(self, domain_id: int, faults: FeedFaults) -> None:
        import rclpy
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import Imu

        self.faults = faults
        self._context = rclpy.Context()
        rclpy.init(context=self._context, domain_id=domain_id)
        self._node = rclpy.create_node(f"fake_mocap_{os.getpid()}", context=self._context)
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT
                         if faults.best_effort else ReliabilityPolicy.RELIABLE)
        self._pose_pub = self._node.create_publisher(
            PoseWithCovarianceStamped, "/voyager/measurement/pose", qos)
        self._imu_pub = self._node.create_publisher(Imu, "/voyager/measurement/imu", qos)
        self._types: tuple[Any, Any] = (PoseWithCovarianceStamped, Imu)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        pose_type, imu_type = self._types
        f = self.faults
        period_s = 1.0 / f.rate_hz
        next_s = time.monotonic()
        sent = 0
        while not self._stop.is_set():
            sent += 1
            occluded = f.nan or (f.nan_every > 0 and sent % f.nan_every == 0)
            stamp_ns = time.time_ns() - round(f.delay_s * NS_PER_S)
            sec, nanosec = divmod(stamp_ns, NS_PER_S)
            pose = pose_type()
            pose.header.stamp.sec, pose.header.stamp.nanosec = sec, nanosec
            pose.header.frame_id = f.frame_id
            x, y, yaw = f.pose
            # The identity transform: arena x, y are the lab's north, east.
            pose.pose.pose.position.x = math.nan if occluded else x
            pose.pose.pose.position.y = y
            pose.pose.pose.orientation.z = math.sin(yaw / 2)
            pose.pose.pose.orientation.w = math.cos(yaw / 2)
            imu = imu_type()
            imu.header.stamp.sec, imu.header.stamp.nanosec = sec, nanosec
            imu.header.frame_id = "voyager/imu_link"
            self._pose_pub.publish(pose)
            self._imu_pub.publish(imu)
            next_s += period_s
            self._stop.wait(max(0.0, next_s - time.monotonic()))

    def close(self) -> None:
        """Stop publishing and shut the node's context down."""
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._node.destroy_node()
        self._context.try_shutdown()

    def __enter__(self) -> FeedPublisher:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def main() -> None:
    """Publish until Ctrl-C with the faults given on the command line."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--domain-id", type=int, default=0)
    parser.add_argument("--best-effort", action="store_true")
    parser.add_argument("--frame-id", default="world_ned")
    parser.add_argument("--rate", type=float, default=100.0)
    parser.add_argument("--delay", type=float, default=0.01)
    parser.add_argument("--nan", action="store_true")
    args = parser.parse_args()
    faults = FeedFaults(best_effort=args.best_effort, frame_id=args.frame_id,
                        rate_hz=args.rate, delay_s=args.delay, nan=args.nan)
    with FeedPublisher(args.domain_id, faults):
        try:
            while True:
                time.sleep(1.0)
        except KeyboardInterrupt:
            pass


if __name__ == "__main__":
    main()
