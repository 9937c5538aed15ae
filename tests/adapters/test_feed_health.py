"""Refusals of sensor messages by reason, each with its fix (no DDS: message doubles)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from hil.adapters.feed_health import (
    FeedMonitor,
    RejectReason,
    frame_refusal,
    imu_value_refusal,
    pose_value_refusal,
    qos_refusal,
    time_refusal,
)

NS = 1_000_000_000


def _pose(x: float = 1.0, q: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)) -> object:
    qx, qy, qz, qw = q
    orientation = SimpleNamespace(x=qx, y=qy, z=qz, w=qw)
    return SimpleNamespace(pose=SimpleNamespace(pose=SimpleNamespace(
        position=SimpleNamespace(x=x, y=2.0), orientation=orientation)))


def test_frame_id_names_the_key_and_the_value_to_set() -> None:
    assert frame_refusal("world_ned", "world_ned") is None
    assert frame_refusal("", "world_ned") is None  # unset frame ids are taken as meant
    refusal = frame_refusal("map", "world_ned")
    assert refusal is not None
    assert refusal.reason is RejectReason.FRAME_ID
    assert refusal.detail == "frame_id 'map' (expected 'world_ned')"
    assert refusal.fix.startswith('set [ros] pose_frame_id = "map"')


def test_nan_and_bad_quaternion_are_told_apart() -> None:
    assert pose_value_refusal(_pose()) is None
    nan = pose_value_refusal(_pose(x=math.nan))
    assert nan is not None
    assert nan.reason is RejectReason.NOT_FINITE
    bad = pose_value_refusal(_pose(q=(0.0, 0.0, 0.0, 0.5)))
    assert bad is not None
    assert bad.reason is RejectReason.BAD_QUATERNION
    assert "norm 0.5" in bad.detail
    imu = SimpleNamespace(linear_acceleration=SimpleNamespace(x=math.inf, y=0.0),
                          angular_velocity=SimpleNamespace(z=0.0))
    refusal = imu_value_refusal(imu)
    assert refusal is not None
    assert refusal.reason is RejectReason.NOT_FINITE


def test_stale_and_out_of_order_stamps() -> None:
    now = 100 * NS
    assert time_refusal(now - NS // 100, None, now, NS, sim_time=False) is None
    stale = time_refusal(now - 3 * NS, None, now, NS, sim_time=False)
    assert stale is not None
    assert stale.reason is RejectReason.STALE
    assert "3 s before hil's wall time" in stale.detail
    assert "use_sim_time" in stale.fix
    # Before /clock the node's time is 0: nothing is judged stale.
    assert time_refusal(5, None, 0, NS, sim_time=True) is None
    late = time_refusal(now - 2 * NS // 100, now - NS // 100, now, NS, sim_time=False)
    assert late is not None
    assert late.reason is RejectReason.OUT_OF_ORDER
    assert "by 10.0 ms" in late.detail


def test_qos_fix_depends_on_the_policy() -> None:
    assert qos_refusal("RELIABILITY", best_effort=False).fix == \
        "set [ros] best_effort_sensors = true"
    assert "DURABILITY" in qos_refusal("DURABILITY", best_effort=True).fix


@pytest.mark.parametrize(("accepted", "head"), [
    (0, "3 poses received, all rejected: "),
    (2, "5 poses received, 3 rejected: "),
])
def test_monitor_describes_what_arrived(accepted: int, head: str) -> None:
    monitor = FeedMonitor("/voyager/measurement/pose", "poses")
    assert monitor.snapshot().describe() == "no poses received"
    refusal = frame_refusal("map", "world_ned")
    assert refusal is not None
    for _ in range(3):
        monitor.received()
        monitor.refused(refusal)
    for stamp_ns in (20, 10)[:accepted]:
        monitor.received()
        monitor.accepted(stamp_ns)
    monitor.refused(qos_refusal("RELIABILITY", best_effort=False), count=2)
    health = monitor.snapshot()
    assert health.rejected == 3  # QoS refusals are publishers, not messages
    assert health.describe().startswith(head + "3 frame_id 'map' (expected 'world_ned')")
    assert [r.reason for r in health.rejections] == [RejectReason.FRAME_ID,
                                                     RejectReason.QOS_INCOMPATIBLE]
    assert health.rejections[1].count == 2
    # The newest stamp accepted, whatever the order they came in.
    assert health.last_ns == (None, 20, 20)[accepted]
