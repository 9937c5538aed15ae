"""The feed statuses of `hil vessel`'s /diagnostics, from the feed's counters."""

from __future__ import annotations

import pytest

from hil.adapters.feed_health import FeedMonitor, frame_refusal
from hil.adapters.ros_telemetry import DiagnosticLevel
from hil.runs.live_diagnostics import feed_status

NS_PER_S = 1_000_000_000
NOW_NS = 100 * NS_PER_S


def _monitor(accepted_at_s: list[float], refused: int = 0) -> FeedMonitor:
    monitor = FeedMonitor("/voyager/measurement/pose", "poses")
    for t_s in accepted_at_s:
        monitor.received()
        monitor.accepted(round(t_s * NS_PER_S))
    refusal = frame_refusal("map", "world_ned")
    assert refusal is not None
    for _ in range(refused):
        monitor.received()
        monitor.refused(refusal)
    return monitor


@pytest.mark.parametrize(("accepted_at_s", "refused", "before", "critical", "level", "says"), [
    ([99.9, 99.99], 0, 0, True, DiagnosticLevel.OK, "newest 10 ms old"),
    ([99.9, 99.99], 3, 1, True, DiagnosticLevel.WARN, "2 refused in the last 1.0 s"),
    ([99.9, 99.99], 3, 3, True, DiagnosticLevel.OK, "none refused lately"),
    ([98.0], 0, 0, True, DiagnosticLevel.ERROR, "no poses for 2.0 s (timeout 0.5 s)"),
    ([98.0], 0, 0, False, DiagnosticLevel.WARN, "no poses for 2.0 s"),
    ([], 4, 4, True, DiagnosticLevel.ERROR,
     "none accepted: 4 poses received, all rejected: 4 frame_id 'map'"),
])
def test_a_feed_status_says_what_is_wrong_with_its_level(
        accepted_at_s: list[float], refused: int, before: int, critical: bool,
        level: DiagnosticLevel, says: str) -> None:
    health = _monitor(accepted_at_s, refused).snapshot()
    status = feed_status("hil_stack: pose feed", health, NOW_NS, 1.0, before, 0.5, critical)
    assert status.level is level
    assert says in status.message
    assert status.hardware_id == "/voyager/measurement/pose"
    values = dict(status.values)
    assert values["accepted"] == str(len(accepted_at_s))
    assert values["rejected"] == str(refused)
    if refused:
        assert 'set [ros] pose_frame_id = "map"' in values["rejected: frame id"]
