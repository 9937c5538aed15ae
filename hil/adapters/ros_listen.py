"""Listening to the vessel's topics without commanding anything (`hil vessel --check`).

:class:`RosListener` subscribes to the pose, IMU and (when configured) obstacle topics
with the QoS `hil vessel` uses, records each message's arrival on the node's clock, its
stamp, frame id and whether its values are finite, and reports the publishers discovery
saw. It creates no publisher at all, so it cannot move the vessel.
"""

from __future__ import annotations

import contextlib
import functools
import math
import threading
import time
from typing import Any

from hil.adapters.feed_tape import FeedTape, Heard
from hil.adapters.ros import (
    RosBackendError,
    RosConfig,
    init_context,
    pose_from_msg,
    spin_in_thread,
    stamp_to_ns,
    stop_spinning,
)
from hil.core.samples import PoseSample, SampleError

__all__ = ["Heard", "RosListener"]


def _finite(*values: Any) -> bool:
    return all(math.isfinite(float(v)) for v in values)


class RosListener:
    """Subscribes to the configured sensor topics and records what arrives.

    Use as a context manager. Its own rclpy context and executor thread.

    Args:
        config: Topics, QoS, clock and domain, as for :class:`hil.adapters.ros.RosWorld`.
    """

    def __init__(self, config: RosConfig) -> None:
        self.config = config
        topics = config.topics
        self._tapes = {"pose": FeedTape(topics.pose), "imu": FeedTape(topics.imu)}
        if topics.obstacles:
            self._tapes["obstacles"] = FeedTape(topics.obstacles)
        self._last_pose: Any = None
        self._context: Any = None
        self._node: Any = None
        self._executor: Any = None
        self._thread: threading.Thread | None = None
        self.domain_id: int | None = None

    def open(self) -> RosListener:
        """Start the node and its subscriptions (no publishers).

        Raises:
            RosBackendError: rclpy or the message packages are missing, or ROS 2
                cannot start on the domain.
        """
        try:
            import rclpy
            from geometry_msgs.msg import PoseArray, PoseWithCovarianceStamped
            from rclpy.event_handler import SubscriptionEventCallbacks
            from rclpy.parameter import Parameter
            from rclpy.qos import QoSProfile, ReliabilityPolicy
            from sensor_msgs.msg import Imu
        except ImportError as err:
            raise RosBackendError(f"the preflight needs rclpy and the ROS message packages "
                                  f"({err})") from err
        cfg = self.config
        self._context = rclpy.Context()
        self.domain_id = init_context(rclpy, self._context, cfg.domain_id, cfg.ros_args)
        self._node = rclpy.create_node(
            f"{cfg.node_name}_check", context=self._context,
            parameter_overrides=[Parameter("use_sim_time", Parameter.Type.BOOL,
                                           cfg.use_sim_time)])
        qos = QoSProfile(depth=cfg.qos_depth, reliability=ReliabilityPolicy.BEST_EFFORT
                         if cfg.best_effort_sensors else ReliabilityPolicy.RELIABLE)
        kinds = {"pose": PoseWithCovarianceStamped, "imu": Imu, "obstacles": PoseArray}
        for name, tape in self._tapes.items():
            events = SubscriptionEventCallbacks(
                incompatible_qos=lambda info, t=tape: setattr(t, "qos_refusals",
                                                               int(info.total_count)))
            # A partial, not a lambda with a default: rclpy passes the message info to
            # callbacks that take two parameters.
            self._node.create_subscription(kinds[name], tape.topic,
                                           functools.partial(self._on_message, name), qos,
                                           event_callbacks=events)
        self._executor, self._thread = spin_in_thread(self._context, self._node, "hil-check")
        return self

    def _on_message(self, name: str, msg: Any) -> None:
        arrival = int(self._node.get_clock().now().nanoseconds)
        if name == "pose":
            p = msg.pose.pose
            o = p.orientation
            finite = _finite(p.position.x, p.position.y, o.x, o.y, o.z, o.w)
            if finite:
                self._last_pose = msg
        elif name == "imu":
            finite = _finite(msg.linear_acceleration.x, msg.linear_acceleration.y,
                             msg.angular_velocity.z)
        else:
            finite = all(_finite(p.position.x, p.position.y) for p in msg.poses)
        self._tapes[name].append(arrival, stamp_to_ns(msg.header.stamp), finite,
                                 str(msg.header.frame_id))

    def wait_first(self, name: str, timeout_s: float) -> bool:
        """Wait up to `timeout_s` (wall, s) for a message on `name`; return whether one came."""
        tape = self._tapes[name]
        end_s = time.monotonic() + timeout_s
        while True:
            if len(tape):
                return True
            if time.monotonic() >= end_s:
                return False
            time.sleep(0.02)

    def restart(self) -> None:
        """Forget the messages recorded so far (QoS refusals and the last pose are kept)."""
        for tape in self._tapes.values():
            tape.clear()

    def heard(self, name: str) -> Heard | None:
        """Return what topic `name` ("pose", "imu", "obstacles") delivered; None: not listened."""
        tape = self._tapes.get(name)
        return None if tape is None else tape.heard()

    def last_pose(self) -> PoseSample | None:
        """Return the last finite pose in the arena frame (the config's transform), if any."""
        msg = self._last_pose
        if msg is None:
            return None
        with contextlib.suppress(SampleError):
            return pose_from_msg(msg, self.config.transform)
        return None

    def publishers(self, topic: str) -> list[str]:
        """Return the reliability (``"RELIABLE"``, ``"BEST_EFFORT"``) of each publisher seen."""
        self._check_open()
        infos = self._node.get_publishers_info_by_topic(topic)
        return [info.qos_profile.reliability.name for info in infos]

    def _check_open(self) -> None:
        if self._node is None:
            raise RosBackendError("the listener is not open")

    def close(self) -> None:
        """Stop the executor, destroy the node and shut the context down."""
        if self._context is None:
            return
        stop_spinning(self._context, self._node, self._executor, self._thread)
        self._context = None
        self._node = None

    def __enter__(self) -> RosListener:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()
