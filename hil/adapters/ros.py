"""The ROS 2 backend: rclpy nodes on the lab's topics (VESSEL.md).

rclpy is imported only when a :class:`RosWorld` opens, so the rest of `hil`
works on machines without ROS, and on the vessel's aarch64 computer the system's
rclpy serves (the PyPI wheels are x86_64 only).

Conversions between ROS messages and samples are plain functions over message
attributes, so they serve rclpy messages and `rosbags` messages alike.
"""

from __future__ import annotations

import math
import re
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from hil.adapters.feed_health import (
    FeedHealth,
    FeedMonitor,
    Refusal,
    RejectReason,
    frame_refusal,
    imu_value_refusal,
    pose_value_refusal,
    qos_refusal,
    time_refusal,
)
from hil.adapters.feed_tape import FeedTape, Heard
from hil.adapters.frames import ArenaTransform
from hil.adapters.ros_context import (
    MAX_DOMAIN_ID,
    RosBackendError,
    check_domain_id,
    init_context,
    spin_in_thread,
    stop_spinning,
)
from hil.adapters.ros_messages import (
    fill_imu_msg,
    fill_pose_msg,
    imu_from_msg,
    pose_from_msg,
    thruster_command_from_components,
    thruster_wrench_components,
)
from hil.core.clock import NS_PER_S, fill_stamp, stamp_to_ns
from hil.core.samples import ImuSample, ObstacleLayout, PoseSample, SampleError, ThrusterCommand

# The message conversions live in ros_messages.py, starting and stopping rclpy in
# ros_context.py; they are part of this backend's API.
__all__ = [
    "MAX_DOMAIN_ID",
    "RosBackendError",
    "RosClock",
    "RosConfig",
    "RosImuSource",
    "RosObstacleSource",
    "RosPoseSource",
    "RosThrusterSink",
    "RosTopics",
    "RosWorld",
    "check_domain_id",
    "fill_imu_msg",
    "fill_obstacle_msg",
    "fill_pose_msg",
    "fill_stamp",
    "imu_from_msg",
    "init_context",
    "pose_from_msg",
    "spin_in_thread",
    "stamp_to_ns",
    "stop_spinning",
    "thruster_command_from_components",
    "thruster_wrench_components",
]

@dataclass(frozen=True, slots=True)
class RosTopics:
    """Topic names; defaults are the lab's (VESSEL.md).

    Attributes:
        pose: The motion capture's vessel pose, geometry_msgs/PoseWithCovarianceStamped.
        imu: The vessel's IMU, sensor_msgs/Imu.
        tunnel: The tunnel thruster's command, geometry_msgs/Wrench (force.x).
        port: The port azimuth's command, geometry_msgs/Wrench (force.x, force.y).
        starboard: The starboard azimuth's command, geometry_msgs/Wrench.
        obstacles: Tracked obstacle centres (lab frame), geometry_msgs/PoseArray, one pose
            per obstacle in the scenario's order; "" keeps the scenario's layout fixed.
    """

    pose: str = "/voyager/measurement/pose"
    imu: str = "/voyager/measurement/imu"
    tunnel: str = "/voyager/thruster/tunnel/command"
    port: str = "/voyager/thruster/port/command"
    starboard: str = "/voyager/thruster/starboard/command"
    obstacles: str = ""
    """geometry_msgs/PoseArray of tracked obstacle centres (lab frame), one pose per
    obstacle in the scenario's order; "" keeps the scenario's layout fixed."""

    def __post_init__(self) -> None:
        for name in ("pose", "imu", "tunnel", "port", "starboard", "obstacles"):
            topic = getattr(self, name)
            if name == "obstacles" and topic == "":
                continue
            if not (isinstance(topic, str) and _TOPIC_NAME.match(topic)):
                raise ValueError(
                    f"topics.{name} = {topic!r} is not a ROS topic name (e.g. "
                    "'/voyager/measurement/pose': letters, digits and '_' between single '/')"
                )


@dataclass(frozen=True, slots=True)
class RosConfig:
    """How the stack talks to the vessel over ROS 2.

    Attributes:
        topics: Topic names.
        transform: Lab NED world and mocap body to the arena frame and body origin.
        qos_depth: History depth of every subscription and publisher.
        best_effort_sensors: Subscribe to pose and IMU with best-effort reliability.
        node_name: Name of the stack's node.
        use_sim_time: Follow `/clock` instead of wall time (tests, simulated vessel).
        pose_frame_id: Expected `header.frame_id` of poses; others are rejected.
        domain_id: ROS_DOMAIN_ID for this world's context; None takes the environment's.
        ros_args: ROS 2 arguments for this world's context, as after ``--ros-args`` on a
            command line: remapping rules (``-r /voyager/measurement/pose:=/mocap/pose``)
            and parameters (``-p use_sim_time:=true``); ``hil vessel ... --ros-args ...``
            appends its own.
        live_telemetry: Publish the run's decisions, events and ``/diagnostics`` while
            ``hil vessel`` runs (:mod:`hil.adapters.ros_telemetry`).
    """

    topics: RosTopics = field(default_factory=RosTopics)
    transform: ArenaTransform = field(default_factory=ArenaTransform)
    qos_depth: int = 10
    best_effort_sensors: bool = False
    node_name: str = "hil_stack"
    use_sim_time: bool = False
    pose_frame_id: str = "world_ned"
    domain_id: int | None = None
    ros_args: tuple[str, ...] = ()
    live_telemetry: bool = True

    def __post_init__(self) -> None:
        if self.qos_depth < 1:
            raise ValueError(f"qos_depth must be at least 1, got {self.qos_depth!r}")
        if self.domain_id is not None:
            check_domain_id(self.domain_id, "domain_id")
        if not _NODE_NAME.match(self.node_name):
            raise ValueError(f"node_name {self.node_name!r} is not a ROS node name "
                             "(letters, digits and '_', not starting with a digit)")


# ROS 2 topic names (design.ros2.org, "Topic and Service name mapping"): tokens of
# letters, digits and underscores, not starting with a digit, joined by single "/".
_TOPIC_NAME = re.compile(r"^(~/|/)?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$")
_NODE_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
# Messages per sensor topic kept for the live diagnostics: 10 s of a 100-Hz feed.
_TAPE_LENGTH = 1000

class _SubscriptionQueue:
    """A thread-safe queue of samples from a subscription callback, with its feed's counters."""

    def __init__(self, monitor: FeedMonitor, maxlen: int = 10_000) -> None:
        self._items: deque[Any] = deque(maxlen=maxlen)
        self._lock = threading.Lock()
        self.monitor = monitor
        self.tape = FeedTape(monitor.topic, maxlen=_TAPE_LENGTH)
        """Every message's arrival, stamp, finiteness and frame, the newest few seconds."""
        self.last_ns: int | None = None
        """Stamp of the newest sample accepted (ns), for the out-of-order check."""
        self.arrived = threading.Event()

    @property
    def rejected(self) -> int:
        return self.monitor.snapshot().rejected

    def put(self, item: Any) -> None:
        with self._lock:
            self._items.append(item)
            self.last_ns = item.t_ns
        self.monitor.accepted(item.t_ns)
        self.arrived.set()

    def drain(self) -> list[Any]:
        with self._lock:
            items = list(self._items)
            self._items.clear()
        return items


class RosPoseSource:
    """Pose samples from the mocap topic, mapped to the arena frame."""

    def __init__(self, inbox: _SubscriptionQueue) -> None:
        self._inbox = inbox

    @property
    def rejected(self) -> int:
        """Number of pose messages refused (by reason: :meth:`RosWorld.pose_health`)."""
        return self._inbox.rejected

    def poll(self) -> list[PoseSample]:
        """Return the poses received since the last call, oldest first."""
        return sorted(self._inbox.drain(), key=lambda s: s.t_ns)

    def wait_first(self, timeout_s: float) -> bool:
        """Wait up to `timeout_s` for the first accepted pose (kept for :meth:`poll`)."""
        return self._inbox.arrived.wait(timeout_s)


class RosImuSource:
    """IMU samples from the IMU topic."""

    def __init__(self, inbox: _SubscriptionQueue) -> None:
        self._inbox = inbox

    @property
    def rejected(self) -> int:
        """Number of IMU messages refused (by reason: :meth:`RosWorld.imu_health`)."""
        return self._inbox.rejected

    def poll(self) -> list[ImuSample]:
        """Return the IMU samples received since the last call, oldest first."""
        return sorted(self._inbox.drain(), key=lambda s: s.t_ns)


class RosObstacleSource:
    """Obstacles tracked by motion capture: the scenario's shapes at the reported centres.

    Motion-capture noise would otherwise make every message a new layout (and a
    re-synthesis): the obstacles move only when some centre moved by `min_move_m`; a
    message that moves none still renews the layout's stamp (the report's time), so
    still obstacles stay fresh for the runtime's report-age check. (The kept positions
    then lag the reported ones by less than `min_move_m`.)

    Args:
        initial: The scenario's layout; obstacle n keeps its size and follows pose n.
        transform: Lab frame to arena frame.
        min_move_m: Smallest move of an obstacle centre that changes the layout (m).
    """

    def __init__(self, initial: ObstacleLayout, transform: ArenaTransform,
                 min_move_m: float = 0.01) -> None:
        self._layout = initial
        self._transform = transform
        self._min_move_m = min_move_m
        self._lock = threading.Lock()
        self.received = 0
        self.rejected = 0

    def latest(self) -> ObstacleLayout:
        """Return the newest reported layout."""
        with self._lock:
            return self._layout

    def on_message(self, msg: Any) -> None:
        """Move each obstacle to its reported centre (a PoseArray in the lab frame)."""
        self.received += 1
        t_ns = stamp_to_ns(msg.header.stamp)
        with self._lock:
            current = self._layout.obstacles
        if len(msg.poses) != len(current):
            self.rejected += 1
            return
        moved = []
        for rect, pose in zip(current, msg.poses, strict=True):
            x, y = self._transform.point_to_arena(float(pose.position.x), float(pose.position.y))
            if not (math.isfinite(x) and math.isfinite(y)):
                self.rejected += 1
                return
            moved.append(rect.translate(x - (rect.x_min_m + rect.x_max_m) / 2,
                                        y - (rect.y_min_m + rect.y_max_m) / 2))
        shift = max((math.hypot(n.x_min_m - o.x_min_m, n.y_min_m - o.y_min_m)
                     for n, o in zip(moved, current, strict=True)), default=0.0)
        with self._lock:
            self._layout = ObstacleLayout(
                t_ns, tuple(moved) if shift >= self._min_move_m else current
            )


def fill_obstacle_msg(msg: Any, layout: ObstacleLayout, transform: ArenaTransform) -> None:
    """Fill a PoseArray with the obstacles' centres in the lab frame (for simulators)."""
    from geometry_msgs.msg import Pose

    fill_stamp(msg.header.stamp, layout.t_ns)
    msg.header.frame_id = "world_ned"
    poses = []
    for rect in layout.obstacles:
        north, east = transform.point_to_lab((rect.x_min_m + rect.x_max_m) / 2,
                                             (rect.y_min_m + rect.y_max_m) / 2)
        pose = Pose()
        pose.position.x, pose.position.y = north, east
        pose.orientation.w = 1.0
        poses.append(pose)
    msg.poses = poses


class RosThrusterSink:
    """Publishes thruster commands as the lab's three Wrench topics."""

    def __init__(self, publishers: dict[str, Any], wrench_type: Any) -> None:
        self._publishers = publishers
        self._wrench_type = wrench_type

    def send(self, command: ThrusterCommand) -> None:
        """Publish one command on the tunnel, port and starboard topics."""
        for name, (fx, fy) in thruster_wrench_components(command).items():
            msg = self._wrench_type()
            msg.force.x, msg.force.y = fx, fy
            self._publishers[name].publish(msg)


class RosClock:
    """The node's clock: wall time, or `/clock` when `use_sim_time` is set.

    Sleeping polls the clock, so a loop on simulated time follows `/clock` at any
    speed and never hangs if `/clock` stops: after `stall_timeout_s` of wall time
    without progress it returns and lets the loop notice the stale feeds.
    """

    def __init__(self, node: Any, poll_s: float = 0.0005, stall_timeout_s: float = 2.0) -> None:
        self._node = node
        self._poll_s = poll_s
        self._stall_timeout_s = stall_timeout_s

    def now_ns(self) -> int:
        """Return the node clock's time (ns)."""
        return int(self._node.get_clock().now().nanoseconds)

    def sleep_until(self, t_ns: int) -> None:
        """Sleep until the node clock reaches `t_ns` (follows `/clock` in sim time)."""
        last = self.now_ns()
        last_progress = time.monotonic()
        while True:
            now = self.now_ns()
            if now >= t_ns:
                return
            if now != last:
                last, last_progress = now, time.monotonic()
            elif time.monotonic() - last_progress > self._stall_timeout_s:
                return
            remaining_s = (t_ns - now) / NS_PER_S
            time.sleep(min(self._poll_s, remaining_s) if self._use_poll() else remaining_s)

    def _use_poll(self) -> bool:
        return bool(self._node.get_clock().ros_time_is_active)


class RosWorld:
    """The stack's view of the vessel over ROS 2: pose, IMU, obstacles, thrusters, clock.

    Use as a context manager; it owns its own rclpy context and executor thread,
    so several can coexist in one process (tests).

    Args:
        config: Topics, QoS, frames and clock settings.
        obstacles: The scenario's layout, tracked when the config names an obstacle topic.
        min_move_m: Smallest move of a tracked centre that changes the layout (m); the
            scenario's ``position_tolerance_m``, by which moving obstacles are grown.
        stale_after_s: A pose or IMU sample stamped this long before the node's clock is
            refused as stale (s): a publisher on another clock, or a feed that lags.
    """

    def __init__(self, config: RosConfig | None = None,
                 obstacles: ObstacleLayout | None = None, min_move_m: float = 0.01,
                 stale_after_s: float = 1.0) -> None:
        self.config = config or RosConfig()
        self._stale_after_ns = round(stale_after_s * NS_PER_S)
        # Tracked obstacles when a topic is configured and the layout to start from given.
        self.obstacle_source: RosObstacleSource | None = None
        if self.config.topics.obstacles and obstacles is not None:
            self.obstacle_source = RosObstacleSource(obstacles, self.config.transform, min_move_m)
        self._pose_inbox = _SubscriptionQueue(FeedMonitor(self.config.topics.pose, "poses"))
        self._imu_inbox = _SubscriptionQueue(FeedMonitor(self.config.topics.imu, "IMU samples"))
        self._context: Any = None
        self._node: Any = None
        self._executor: Any = None
        self._thread: threading.Thread | None = None
        self.pose_source = RosPoseSource(self._pose_inbox)
        self.imu_source = RosImuSource(self._imu_inbox)
        self.thruster_sink: RosThrusterSink | None = None
        self.clock: RosClock | None = None
        self.domain_id: int | None = None
        """The domain the world joined (from the config or ROS_DOMAIN_ID), once open."""

    def open(self) -> RosWorld:
        """Start the node, its subscriptions and publishers, and the executor thread.

        Raises:
            RosBackendError: If rclpy or the message packages cannot be imported.
        """
        try:
            import rclpy
            from geometry_msgs.msg import PoseWithCovarianceStamped, Wrench
            from rclpy.event_handler import SubscriptionEventCallbacks
            from rclpy.parameter import Parameter
            from rclpy.qos import QoSProfile, ReliabilityPolicy
            from sensor_msgs.msg import Imu
        except ImportError as err:
            raise RosBackendError(
                "the ROS backend needs rclpy and the geometry_msgs/sensor_msgs packages: "
                "install the 'ros' extra (x86_64) or source a ROS 2 Jazzy install "
                f"({err})"
            ) from err
        cfg = self.config
        self._context = rclpy.Context()
        self.domain_id = init_context(rclpy, self._context, cfg.domain_id, cfg.ros_args)
        overrides = [Parameter("use_sim_time", Parameter.Type.BOOL, cfg.use_sim_time)]
        self._node = rclpy.create_node(
            cfg.node_name, context=self._context, parameter_overrides=overrides
        )
        sensor_qos = QoSProfile(
            depth=cfg.qos_depth,
            reliability=(
                ReliabilityPolicy.BEST_EFFORT
                if cfg.best_effort_sensors
                else ReliabilityPolicy.RELIABLE
            ),
        )
        for msg_type, topic, callback, inbox in (
                (PoseWithCovarianceStamped, cfg.topics.pose, self._on_pose, self._pose_inbox),
                (Imu, cfg.topics.imu, self._on_imu, self._imu_inbox)):
            # The event replaces rclpy's one-off warning: the refusal is counted and named.
            events = SubscriptionEventCallbacks(
                incompatible_qos=lambda info, box=inbox: self._on_incompatible_qos(box, info))
            self._node.create_subscription(msg_type, topic, callback, sensor_qos,
                                           event_callbacks=events)
        if self.obstacle_source is not None:
            from geometry_msgs.msg import PoseArray

            self._node.create_subscription(PoseArray, cfg.topics.obstacles,
                                           self.obstacle_source.on_message, sensor_qos)
        publishers = {
            name: self._node.create_publisher(Wrench, getattr(cfg.topics, name), cfg.qos_depth)
            for name in ("tunnel", "port", "starboard")
        }
        self.thruster_sink = RosThrusterSink(publishers, Wrench)
        self.clock = RosClock(self._node)
        self._executor, self._thread = spin_in_thread(self._context, self._node, "hil-ros")
        return self

    def pose_health(self) -> FeedHealth:
        """Return what the pose topic delivered and refused so far, by reason."""
        return self._pose_inbox.monitor.snapshot()

    def imu_health(self) -> FeedHealth:
        """Return what the IMU topic delivered and refused so far, by reason."""
        return self._imu_inbox.monitor.snapshot()

    def heard(self, since_ns: int | None = None) -> tuple[Heard, Heard]:
        """Return the pose and IMU messages that arrived since `since_ns` (node clock, ns).

        Only the newest few seconds are kept (:data:`_TAPE_LENGTH` messages per topic).
        """
        return self._pose_inbox.tape.heard(since_ns), self._imu_inbox.tape.heard(since_ns)

    @property
    def node(self) -> Any:
        """The world's rclpy node, for publishers beside the thrusters' (None before open)."""
        return self._node

    def publishers_on(self, topic: str) -> int:
        """Return how many publishers discovery has seen on `topic` (0 before :meth:`open`)."""
        return 0 if self._node is None else int(self._node.count_publishers(topic))

    def _on_incompatible_qos(self, inbox: _SubscriptionQueue, info: Any) -> None:
        from rclpy.qos import QoSPolicyKind

        try:
            policy = QoSPolicyKind(info.last_policy_kind).name
        except ValueError:
            policy = str(info.last_policy_kind)
        inbox.monitor.refused(qos_refusal(policy, self.config.best_effort_sensors),
                              count=int(info.total_count))

    def _arrived(self, inbox: _SubscriptionQueue, msg: Any, value: Refusal | None) -> int:
        """Count and tape a message as it arrives; return the node clock's time (ns)."""
        now_ns = int(self._node.get_clock().now().nanoseconds)
        inbox.monitor.received()
        finite = value is None or value.reason is not RejectReason.NOT_FINITE
        inbox.tape.append(now_ns, stamp_to_ns(msg.header.stamp), finite,
                          str(msg.header.frame_id))
        return now_ns

    def _time_refusal(self, inbox: _SubscriptionQueue, msg: Any, now_ns: int) -> Refusal | None:
        return time_refusal(stamp_to_ns(msg.header.stamp), inbox.last_ns, now_ns,
                            self._stale_after_ns, self.config.use_sim_time)

    def _on_pose(self, msg: Any) -> None:
        inbox = self._pose_inbox
        value = pose_value_refusal(msg)
        now_ns = self._arrived(inbox, msg, value)
        refusal = (frame_refusal(msg.header.frame_id, self.config.pose_frame_id)
                   or value or self._time_refusal(inbox, msg, now_ns))
        if refusal is None:
            try:
                inbox.put(pose_from_msg(msg, self.config.transform))
                return
            except SampleError as err:  # the transform's checks, beyond the message's
                refusal = Refusal(RejectReason.NOT_FINITE, f"poses refused ({err})",
                                  "check [ros.transform]")
        inbox.monitor.refused(refusal)

    def _on_imu(self, msg: Any) -> None:
        inbox = self._imu_inbox
        value = imu_value_refusal(msg)
        refusal = value or self._time_refusal(inbox, msg, self._arrived(inbox, msg, value))
        if refusal is None:
            inbox.put(imu_from_msg(msg))
        else:
            inbox.monitor.refused(refusal)

    def close(self) -> None:
        """Stop the executor, destroy the node and shut the context down."""
        if self._context is None:
            return
        stop_spinning(self._context, self._node, self._executor, self._thread)
        self._context = None

    def __enter__(self) -> RosWorld:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()
