"""The preflight's judgement over recorded arrival and stamp series (no DDS)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.core.pose_feeds import pose_feed
from hil.runs.feed_check import (
    CheckLine,
    FeedSeries,
    PositionFinding,
    feed_figures,
    judge_imu_feed,
    judge_pose_feed,
    judge_position,
    judge_publishers,
)

NS = 1_000_000_000
TOPIC = "/voyager/measurement/pose"


def _series(rate_hz: float, delay_ms: float, seconds: float = 2.0, nan_every: int = 0,
            frame: str = "world_ned", jitter_ms: float = 0.5, seed: int = 0) -> FeedSeries:
    """Capture times on a regular grid; arrivals `delay_ms` later, with uniform jitter."""
    rng = np.random.default_rng(seed)
    n = int(seconds * rate_hz)
    capture = 1_700_000_000 * NS + np.round(np.arange(n) * NS / rate_hz).astype(np.int64)
    arrival = capture + np.round(delay_ms * 1e6 + rng.uniform(0, jitter_ms * 1e6, n)).astype(
        np.int64)
    finite = np.ones(n, dtype=np.bool_)
    if nan_every:
        finite[::nan_every] = False
    return FeedSeries(TOPIC, arrival, capture, finite, (frame,) * n)


def _by_what(lines: list[CheckLine]) -> dict[str, CheckLine]:
    return {line.what: line for line in lines}


def test_figures_of_a_regular_feed() -> None:
    figures = feed_figures(_series(100.0, 10.0, jitter_ms=0.0))
    assert figures.count == 200
    assert figures.rate_hz == pytest.approx(100.0)
    assert figures.jitter_ms == pytest.approx(0.0, abs=1e-6)
    assert figures.latency_ms == pytest.approx(10.0)
    assert figures.nan_share == 0.0
    assert figures.frame_ids == ("world_ned",)


def test_the_premise_feed_passes_every_line() -> None:
    lines = judge_pose_feed(_series(100.0, 10.0), "world_ned", sim_time=False)
    assert [line.what for line in lines] == ["rate", "jitter", "time source", "latency",
                                             "NaN share", "frame id"]
    assert all(line.ok for line in lines), [line.text() for line in lines]
    assert lines[0].text().startswith("PASS  /voyager/measurement/pose  rate: 100.0 Hz")


def test_ten_hertz_stamped_on_receipt_is_another_premise() -> None:
    lines = _by_what(judge_pose_feed(_series(10.0, 0.2), "world_ned", sim_time=False))
    assert not lines["rate"].ok
    assert "slower than the premise in force (pose_feed = \"qtm-100hz\"" in lines["rate"].fix
    assert 'set pose_feed = "ros-10hz-receive-stamped"' in lines["rate"].fix
    assert not lines["latency"].ok
    assert "stamped on receipt?" in lines["latency"].value
    assert lines["latency"].text().startswith("FAIL")
    assert "stamp each sample at capture" in lines["latency"].fix
    assert lines["time source"].ok


def test_nan_share_and_frame_id_and_clock() -> None:
    lines = _by_what(judge_pose_feed(_series(100.0, 10.0, nan_every=10, frame="map"),
                                     "world_ned", sim_time=False))
    assert not lines["NaN share"].ok
    assert lines["NaN share"].value == "10.0 %"
    assert not lines["frame id"].ok
    assert lines["frame id"].fix.startswith('set [ros] pose_frame_id = "map"')
    # Wall-clock stamps seen by a node on /clock (near 0): another time base.
    wall = _series(100.0, 10.0)
    sim = FeedSeries(TOPIC, wall.arrival_ns - wall.arrival_ns[0] + NS, wall.stamp_ns,
                     wall.finite, wall.frame_ids)
    clock = _by_what(judge_pose_feed(sim, "world_ned", sim_time=True))
    assert not clock["time source"].ok
    assert "/clock (sim time)" in clock["time source"].value
    assert "latency" not in clock  # meaningless across clocks


def test_an_empty_feed_fails_on_one_line() -> None:
    empty = FeedSeries(TOPIC, np.zeros(0, np.int64), np.zeros(0, np.int64),
                       np.zeros(0, np.bool_))
    (line,) = judge_imu_feed(empty, sim_time=False)
    assert not line.ok
    assert line.value == "0 received"


def test_qos_line_names_the_fix() -> None:
    line = judge_publishers(TOPIC, ["BEST_EFFORT"], best_effort=False, qos_refusals=1)
    assert not line.ok
    assert line.fix == "set [ros] best_effort_sensors = true"
    assert judge_publishers(TOPIC, ["BEST_EFFORT"], best_effort=True, qos_refusals=0).ok
    assert judge_publishers(TOPIC, ["RELIABLE"], best_effort=False, qos_refusals=0).ok
    none = judge_publishers(TOPIC, [], best_effort=False, qos_refusals=0)
    assert not none.ok
    assert "ROS_DOMAIN_ID" in none.fix


def test_position_lines() -> None:
    good = judge_position(PositionFinding((0.0, -1.0, math.pi), True, 42, 81.0), "coarse")
    assert all(line.ok for line in good)
    assert good[2].value == "value 81 steps at rest"
    lost = judge_position(PositionFinding((9.0, 0.0, 0.0), False, -1, math.inf), "coarse")
    assert [line.ok for line in lost] == [False, False, False]
    (none,) = judge_position(PositionFinding(None, False, -1, math.inf), "coarse")
    assert not none.ok


def test_the_ten_hertz_premise_passes_a_ten_hertz_receipt_stamped_feed() -> None:
    feed = pose_feed("ros-10hz-receive-stamped")
    lines = _by_what(judge_pose_feed(_series(10.0, 0.2), "world_ned", False, feed))
    assert all(line.ok for line in lines.values()), [line.text() for line in lines.values()]
    assert "premise: 9-11 Hz" in lines["rate"].text()


def test_a_feed_slower_than_the_ten_hertz_premise_fails_naming_no_faster_premise() -> None:
    feed = pose_feed("ros-10hz-receive-stamped")
    rate = _by_what(judge_pose_feed(_series(5.0, 0.2), "world_ned", False, feed))["rate"]
    assert not rate.ok
    assert "delivers 5.0 Hz, slower than the premise in force" in rate.fix
    assert "set pose_feed" not in rate.fix  # no premise covers a 5-Hz feed
