"""`hil sim-vessel --config FILE`: the simulated vessel on a vessel config's topics and frame."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from tests.runs.dds_processes import dds_env, own_domain, stop

pytest.importorskip("rclpy")

HIL = [sys.executable, "-m", "hil"]


def _frames_on(domain: int, topic: str, seconds: float) -> list[str]:
    """Listen on `topic` (PoseWithCovarianceStamped) for `seconds` after the first message
    (waiting up to 60 s for it); return the frame ids."""
    import rclpy
    from geometry_msgs.msg import PoseWithCovarianceStamped
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain)
    node = rclpy.create_node(f"listener_{os.getpid()}", context=context)
    frames: list[str] = []
    lock = threading.Lock()

    def on_pose(msg: Any) -> None:
        with lock:
            frames.append(str(msg.header.frame_id))

    node.create_subscription(PoseWithCovarianceStamped, topic, on_pose, 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    deadline = time.monotonic() + 60.0
    with contextlib.suppress(ExternalShutdownException):
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
            if frames and deadline - time.monotonic() > seconds:
                deadline = time.monotonic() + seconds
    context.try_shutdown()
    return frames


def _heard(domain: int, topic: str, args: list[str]) -> tuple[list[str], str]:
    """Run `hil sim-vessel ARGS`, listen on `topic`; return the frame ids and its stderr."""
    vessel = subprocess.Popen(
        [*HIL, "sim-vessel", *args],
        env=dds_env(domain), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        frames = _frames_on(domain, topic, 2.0)
    finally:
        stop(vessel)
    assert vessel.stderr is not None
    with vessel.stderr:
        return frames, vessel.stderr.read()


def test_the_sim_vessel_publishes_on_the_configs_topic_and_frame(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    domain = own_domain(1, 19, offset=1)
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    config = tmp_path / "vessel.toml"
    config.write_text(f"""
scenario = "coarse"
[ros]
domain_id = {domain}
pose_frame_id = "map"
[ros.topics]
pose = "/mocap/voyager/pose"
""")
    frames, err = _heard(domain, "/mocap/voyager/pose",
                         ["--config", str(config), "--duration", "30"])
    assert "publishing pose on /mocap/voyager/pose" in err
    assert f"ROS domain {domain}" in err
    assert len(frames) > 50, err[-2000:]
    assert set(frames) == {"map"}


def test_a_bad_config_is_refused_in_one_line(tmp_path: Path) -> None:
    config = tmp_path / "vessel.toml"
    config.write_text('[ros.topics]\npose = "not a topic"\n')
    done = subprocess.run([*HIL, "sim-vessel", "--config", str(config)],
                          capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1].startswith("hil sim-vessel: error:")
    assert "pose" in done.stderr


def test_ros_args_remap_the_sim_vessels_topics(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    domain = own_domain(1, 19, offset=2)
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    frames, err = _heard(domain, "/remapped/pose",
                         ["coarse", "--domain-id", str(domain), "--duration", "30",
                          "--ros-args", "-r", "/voyager/measurement/pose:=/remapped/pose"])
    assert len(frames) > 50, err[-2000:]
    assert set(frames) == {"world_ned"}
