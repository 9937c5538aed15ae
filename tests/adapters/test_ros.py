"""The ROS 2 backend over real DDS on loopback (skipped where rclpy is absent)."""

from __future__ import annotations

import itertools
import math
import os
import time
from collections.abc import Iterator
from typing import Any

import pytest

from hil.adapters.frames import ArenaTransform
from hil.adapters.ros import (
    RosConfig,
    RosTopics,
    RosWorld,
    fill_imu_msg,
    fill_obstacle_msg,
    fill_pose_msg,
    imu_from_msg,
    pose_from_msg,
    thruster_command_from_components,
    thruster_wrench_components,
)
from hil.core.samples import (
    Frame,
    ImuSample,
    ObstacleLayout,
    PoseSample,
    ThrusterCommand,
)
from hil.core.shapes import Rect

rclpy = pytest.importorskip("rclpy")
pytest.importorskip("rclpy.executors")
geometry_msgs = pytest.importorskip("geometry_msgs.msg")
sensor_msgs = pytest.importorskip("sensor_msgs.msg")

pytestmark = pytest.mark.ros

TRANSFORM = ArenaTransform(origin_north_m=1.0, origin_east_m=-2.0, yaw_rad=0.3, body_offset_x_m=0.1)


def _domain_id() -> int:
    # One domain per test process (xdist worker) keeps parallel tests apart.
    worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0")
    return 100 + int(worker.removeprefix("gw") or 0) + (os.getpid() % 50) * 2


@pytest.fixture(autouse=True)
def _localhost_only(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")


def test_pose_message_round_trip_through_lab_frame() -> None:
    arena = PoseSample(1_500_000_123, 2.5, -1.0, 2.9, Frame.ARENA)
    msg = geometry_msgs.PoseWithCovarianceStamped()
    fill_pose_msg(msg, arena, TRANSFORM)
    assert msg.header.stamp.sec == 1
    assert msg.header.stamp.nanosec == 500_000_123
    back = pose_from_msg(msg, TRANSFORM)
    assert back.frame is Frame.ARENA
    assert back.t_ns == arena.t_ns
    assert back.x_m == pytest.approx(arena.x_m)
    assert back.y_m == pytest.approx(arena.y_m)
    assert math.cos(back.yaw_rad - arena.yaw_rad) == pytest.approx(1.0)


def test_imu_message_round_trip() -> None:
    imu = ImuSample(42, 0.1, -0.2, 0.05)
    msg = sensor_msgs.Imu()
    fill_imu_msg(msg, imu)
    assert imu_from_msg(msg) == imu
    assert msg.orientation_covariance[0] == -1.0


def test_thruster_components_round_trip() -> None:
    cmd = ThrusterCommand(5, 0.3, 0.8, -0.4, 1.2, -2.0)
    parts = thruster_wrench_components(cmd)
    back = thruster_command_from_components(
        5, parts["tunnel"][0], parts["port"], parts["starboard"], previous=cmd
    )
    assert back.tunnel == pytest.approx(0.3)
    assert back.port == pytest.approx(0.8)
    assert back.port_angle_rad == pytest.approx(1.2)
    # The vector alone cannot tell a reversed propeller: the pod keeps its side.
    assert back.starboard == pytest.approx(-0.4)
    assert back.starboard_angle_rad == pytest.approx(-2.0)
    # Without a previous angle, the reference angles decide the side.
    fresh = thruster_command_from_components(5, 0.0, (0.0, -0.5), (0.0, 0.5))
    assert fresh.port == pytest.approx(-0.5)
    assert fresh.port_angle_rad == pytest.approx(math.pi / 2)
    assert fresh.starboard == pytest.approx(-0.5)


_NAMES = itertools.count()


class _Peer:
    """A plain rclpy node in its own context playing the vessel's side."""

    def __init__(self, domain_id: int) -> None:
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node(f"peer_{os.getpid()}_{next(_NAMES)}", context=self.context)
        self.pose_pub = self.node.create_publisher(
            geometry_msgs.PoseWithCovarianceStamped, "/voyager/measurement/pose", 10
        )
        self.imu_pub = self.node.create_publisher(sensor_msgs.Imu, "/voyager/measurement/imu", 10)
        self.executor = rclpy.executors.SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.wrenches: dict[str, list[Any]] = {"tunnel": [], "port": [], "starboard": []}
        for name, box in self.wrenches.items():
            self.node.create_subscription(
                geometry_msgs.Wrench, f"/voyager/thruster/{name}/command", box.append, 10
            )

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.01)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()


@pytest.fixture
def peer_and_world() -> Iterator[tuple[_Peer, RosWorld]]:
    domain = _domain_id()
    peer = _Peer(domain)
    world = RosWorld(
        RosConfig(
            transform=TRANSFORM, domain_id=domain, node_name=f"stack_{os.getpid()}_{next(_NAMES)}"
        )
    )
    world.open()
    try:
        yield peer, world
    finally:
        world.close()
        peer.close()


def _wait_for(predicate: Any, peer: _Peer, timeout_s: float = 10.0) -> None:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        peer.spin_for(0.05)
        if predicate():
            return
    pytest.fail("timed out waiting for DDS traffic")


def test_dds_pose_in_lab_frame_lands_at_arena_state(
    peer_and_world: tuple[_Peer, RosWorld],
) -> None:
    peer, world = peer_and_world
    assert world.clock is not None
    # Stamped now: the backend refuses poses older than its clock by a second (stale).
    expected = PoseSample(world.clock.now_ns(), 1.5, 0.5, -0.7, Frame.ARENA)
    msg = geometry_msgs.PoseWithCovarianceStamped()
    fill_pose_msg(msg, expected, TRANSFORM)
    bad = geometry_msgs.PoseWithCovarianceStamped()
    bad.header.frame_id = "world_ned"
    bad.pose.pose.position.x = math.nan
    bad.pose.pose.orientation.w = 1.0
    received: list[PoseSample] = []

    def got_one() -> bool:
        peer.pose_pub.publish(msg)
        peer.pose_pub.publish(bad)
        received.extend(world.pose_source.poll())
        return bool(received) and world.pose_source.rejected > 0

    _wait_for(got_one, peer)
    pose = received[0]
    assert pose.frame is Frame.ARENA
    assert pose.x_m == pytest.approx(1.5)
    assert pose.y_m == pytest.approx(0.5)
    assert pose.yaw_rad == pytest.approx(-0.7)
    assert pose.t_ns == expected.t_ns


def test_dds_thruster_commands_reach_the_vessel(peer_and_world: tuple[_Peer, RosWorld]) -> None:
    peer, world = peer_and_world
    assert world.thruster_sink is not None
    command = ThrusterCommand(0, 0.5, 0.2, 0.3, math.pi / 2, -math.pi / 2)

    def delivered() -> bool:
        world.thruster_sink.send(command)  # type: ignore[union-attr]
        return all(peer.wrenches.values())

    _wait_for(delivered, peer)
    assert peer.wrenches["tunnel"][-1].force.x == pytest.approx(0.5)
    assert peer.wrenches["port"][-1].force.y == pytest.approx(0.2)
    assert peer.wrenches["starboard"][-1].force.y == pytest.approx(-0.3)


def test_dds_tracked_obstacles_move_the_layout() -> None:
    domain = _domain_id() + 1
    o1, o2 = Rect(1.75, 2.25, -3.0, 0.0), Rect(-1.25, -0.75, 0.0, 3.0)
    initial = ObstacleLayout(0, (o1, o2))
    config = RosConfig(transform=TRANSFORM, domain_id=domain,
                       topics=RosTopics(obstacles="/voyager/obstacles"),
                       node_name=f"stack_{os.getpid()}_{next(_NAMES)}")
    peer = _Peer(domain)
    publisher = peer.node.create_publisher(geometry_msgs.PoseArray, "/voyager/obstacles", 10)
    moved = ObstacleLayout(3_000_000_000, (initial.obstacles[0].translate(0.3, 0.0),
                                           initial.obstacles[1].translate(0.0, -0.2)))
    msg = geometry_msgs.PoseArray()
    fill_obstacle_msg(msg, moved, TRANSFORM)
    jitter = geometry_msgs.PoseArray()  # a 2-mm wobble must not count as a move
    fill_obstacle_msg(jitter, ObstacleLayout(1, (initial.obstacles[0].translate(0.002, 0.0),
                                                 initial.obstacles[1])), TRANSFORM)
    with RosWorld(config, obstacles=initial) as world:
        source = world.obstacle_source
        assert source is not None
        try:

            def wobbled() -> bool:
                publisher.publish(jitter)
                return source.received >= 3

            _wait_for(wobbled, peer)
            assert source.latest().obstacles == initial.obstacles  # not moved...
            assert source.latest().t_ns == 1  # ...but reported again

            def arrived() -> bool:
                publisher.publish(msg)
                return source.latest().t_ns == moved.t_ns

            _wait_for(arrived, peer)
        finally:
            peer.close()
    got = source.latest().obstacles
    for a, b in zip(got, moved.obstacles, strict=True):
        assert a.x_min_m == pytest.approx(b.x_min_m)
        assert a.y_max_m == pytest.approx(b.y_max_m)
