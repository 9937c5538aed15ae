"""End to end over real DDS: `hil vessel` names why the pose feed is refused, and the fix.

A stand-in for the lab's mocap driver (:mod:`tests.runs.feed_publishers`) publishes
with a fault drivers have; `hil vessel` must say the cause and the fix within 5 s of
waiting for the pose, write it as events into the run's log and into the summary.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from hil.adapters.ros import RosConfig, RosWorld
from hil.bag.reader import BagReader
from hil.core.records import Event
from hil.runs.feed_watch import FeedWatch
from hil.runtime.trace import MemoryLog
from tests.runs.dds_processes import LineTimes, dds_env, own_domain, stop

pytest.importorskip("rclpy")
pytestmark = pytest.mark.ros

from tests.runs.feed_publishers import FeedFaults, FeedPublisher  # noqa: E402

HIL = [sys.executable, "-m", "hil"]


@pytest.mark.parametrize(("offset", "faults", "cause", "fix"), [
    (0, FeedFaults(best_effort=True), "incompatible QoS (RELIABILITY",
     "set [ros] best_effort_sensors = true"),
    (1, FeedFaults(frame_id="map"), "frame_id 'map' (expected 'world_ned')",
     'set [ros] pose_frame_id = "map"'),
    (2, FeedFaults(nan=True), "NaN or infinite poses",
     "check the mocap sees and tracks the vessel's rigid body"),
], ids=["best-effort", "frame-map", "nan"])
def test_vessel_names_the_cause_and_the_fix(tmp_path: Path, offset: int, faults: FeedFaults,
                                            cause: str, fix: str) -> None:
    domain = own_domain(20, 40, offset)
    config = tmp_path / "vessel.toml"
    config.write_text(f'scenario = "coarse"\n[ros]\ndomain_id = {domain}\n')
    out = tmp_path / "run"
    with FeedPublisher(domain, faults), subprocess.Popen(
            [*HIL, "vessel", "--config", str(config), "--out", str(out)],
            env=dds_env(domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            text=True) as stack:
        assert stack.stderr is not None
        assert stack.stdout is not None
        lines = LineTimes(stack.stderr)
        try:
            waiting = lines.wait_for("waiting for pose on /voyager/measurement/pose", 120.0)
            assert waiting is not None, lines.text()
            named = lines.wait_for(fix, 5.0)
            assert named is not None, lines.text()
            assert named - waiting < 5.0
            # The reminder says what the topic delivered (nothing, for QoS), not a guess.
            reminder = lines.wait_for("still waiting for pose", 8.0)
            assert reminder is not None, lines.text()
        finally:
            status = stop(stack)
        stdout = stack.stdout.read()
    text = lines.text()
    assert status == 1, text
    reminders = [line for line in text.splitlines() if "still waiting for pose" in line]
    assert cause in reminders[0]
    assert fix in reminders[0]
    assert "is the motion capture publishing?" not in text
    # The summary names the refusal, with its fix.
    summary = text + stdout
    assert "refused by the ROS backend: /voyager/measurement/pose" in summary
    assert fix in summary.split("refused by the ROS backend")[1]
    with BagReader(out) as reader:
        events = [r for _, _, r in reader.records(["/hil/events"]) if isinstance(r, Event)]
    refused = [e for e in events if e.code == "sample_rejected"]
    assert refused, [e.text for e in events]
    assert cause in refused[0].text
    assert fix in refused[0].text


def test_status_and_events_count_refusals_while_poses_flow() -> None:
    # One pose in four occluded: the run goes on, and says what it refuses and why.
    domain = own_domain(20, 40, 3)
    log = MemoryLog()
    said: list[str] = []
    with FeedPublisher(domain, FeedFaults(nan_every=4)), \
            RosWorld(RosConfig(domain_id=domain, node_name=f"stack_{domain}")) as ros:
        watch = FeedWatch(ros, log, said.append, period_s=0.0)
        deadline = time.monotonic() + 15.0
        while time.monotonic() < deadline and ros.pose_health().rejected < 10:
            time.sleep(0.1)
        watch.poll()
        first = ros.pose_health()
        time.sleep(0.3)
        watch.poll()
        status = watch.status()
        assert ros.pose_source.poll(), "the finite poses are taken"
    assert first.accepted >= 2 * first.rejected
    assert len(said) == 1  # a new reason is said once...
    assert said[0].startswith("poses on /voyager/measurement/pose refused: ")
    assert len(log.events) == 2  # ...and logged each time its count grew
    assert {code for _, _, code, _ in log.events} == {"sample_rejected"}
    assert status.startswith("; refused pose ")
    assert "NaN or infinite poses" in status
    assert "check the mocap sees and tracks the vessel's rigid body" in status
    assert watch.summary()[0].startswith("/voyager/measurement/pose: ")
    assert "rejected: " in watch.summary()[0]


def test_vessel_refuses_a_ten_hertz_feed_naming_the_premise_that_covers_it(
        tmp_path: Path) -> None:
    """The lab's ROS driver: 10 Hz, stamped on receipt, under the default 100-Hz premise.

    Poses flow and pass every per-sample check, so only the rate tells: `hil vessel`
    measures it over the first second and refuses to claim the guarantee on it, naming
    the premise that covers such a feed, before any command (exit 2, the refusal in the log).
    """
    domain = own_domain(20, 40, 3)
    config = tmp_path / "vessel.toml"
    config.write_text(f'scenario = "coarse"\n[ros]\ndomain_id = {domain}\n')
    out = tmp_path / "run"
    fix = 'or set pose_feed = "ros-10hz-receive-stamped"'
    with FeedPublisher(domain, FeedFaults(rate_hz=10.0, delay_s=0.0)), subprocess.Popen(
            [*HIL, "vessel", "--config", str(config), "--out", str(out)],
            env=dds_env(domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            text=True) as stack:
        assert stack.stderr is not None
        lines = LineTimes(stack.stderr)
        try:
            waiting = lines.wait_for("waiting for pose on /voyager/measurement/pose", 120.0)
            assert waiting is not None, lines.text()
            named = lines.wait_for(fix, 10.0)
            assert named is not None, lines.text()
            assert named - waiting < 5.0
            status = stack.wait(timeout=30)
        finally:
            if stack.poll() is None:
                stop(stack)
    text = lines.text()
    assert status == 2, text
    assert "slower than the premise in force (pose_feed = \"qtm-100hz\"" in text
    with BagReader(out) as reader:
        events = [r for _, _, r in reader.records(["/hil/events"]) if isinstance(r, Event)]
        thrusts = list(reader.records(["/hil/thrusters"]))
    refused = [e for e in events if e.code == "pose_feed_premise"]
    assert refused, [e.text for e in events]
    assert fix in refused[0].text
    assert not thrusts  # refused before the first command
