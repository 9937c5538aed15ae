"""The pose feed against the premise in force: a slower feed is refused, naming the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.adapters.qtm import QtmConfig
from hil.core.config import ConfigError
from hil.core.pose_feeds import DEFAULT_POSE_FEED, pose_feed
from hil.runs.feed_premise import measure_rate, qtm_rate_refusal, rate_refusal
from hil.runs.vessel_config import VesselConfig

QTM = pose_feed(DEFAULT_POSE_FEED)
ROS = pose_feed("ros-10hz-receive-stamped")


def test_a_feed_at_its_premise_is_not_refused() -> None:
    assert rate_refusal(95.0, QTM, "QTM") == ""
    assert rate_refusal(9.5, ROS, "the topic") == ""
    assert rate_refusal(100.0, ROS, "the topic") == ""  # faster than the premise


def test_a_slower_feed_is_refused_with_the_key_to_change() -> None:
    text = rate_refusal(10.0, QTM, "the pose feed on /pose")
    assert text.startswith("the pose feed on /pose delivers 10.0 Hz, slower than the premise")
    assert 'pose_feed = "qtm-100hz": 100 Hz, stamped at capture; at least 90 Hz' in text
    assert 'set pose_feed = "ros-10hz-receive-stamped" to run with its wider bound' in text


def test_a_slow_qtm_rate_is_refused_when_the_config_is_read(tmp_path: Path) -> None:
    assert qtm_rate_refusal(QtmConfig("qtm", "2"), QTM) == ""  # every camera frame
    assert "set [qtm] rate_hz to at least 100" in qtm_rate_refusal(
        QtmConfig("qtm", "2", rate_hz=10), QTM)
    config = tmp_path / "vessel.toml"
    config.write_text('scenario = "coarse"\n[qtm]\nhost = "qtm"\nbody = "2"\nrate_hz = 10\n')
    with pytest.raises(ConfigError, match=r"key qtm.'rate_hz' = 10 is slower than the premise"):
        VesselConfig.load(config)
    config.write_text('scenario = "coarse"\npose_feed = "ros-10hz-receive-stamped"\n'
                      '[qtm]\nhost = "qtm"\nbody = "2"\nrate_hz = 10\n')
    assert VesselConfig.load(config).pose_feed == "ros-10hz-receive-stamped"


def test_an_unknown_pose_feed_is_refused_naming_the_key(tmp_path: Path) -> None:
    config = tmp_path / "vessel.toml"
    config.write_text('pose_feed = "vicon"\n')
    with pytest.raises(ConfigError, match=r"key 'pose_feed' = 'vicon': one of qtm-100hz, ros-10hz"):
        VesselConfig.load(config)


def _still(t_s: float) -> tuple[float, float, float]:
    return 1.0, -1.0, 0.5


@pytest.mark.parametrize(("rate_hz", "refused"), [(100.0, False), (10.0, True)])
def test_a_qtm_feed_is_measured_and_judged_against_the_premise(rate_hz: float,
                                                               refused: bool) -> None:
    pytest.importorskip("qtm_rt")
    from hil.adapters.qtm import QtmPoseSource
    from hil.core.clock import WallClock
    from tests.adapters.qtm_server import QtmTestServer

    with QtmTestServer(_still, rate_hz=rate_hz) as server, QtmPoseSource(
            QtmConfig("127.0.0.1", "2", port=server.port), WallClock()) as source:
        assert source.wait_first(10.0)
        window = measure_rate(lambda: source.counters.poses, 1.0)
    assert window.rate_hz == pytest.approx(rate_hz, rel=0.3)
    text = rate_refusal(window.rate_hz, QTM, "QTM", window.fastest_hz)
    assert bool(text) == refused, text
    # The 10-Hz premise takes either.
    assert rate_refusal(window.rate_hz, ROS, "QTM", window.fastest_hz) == ""
