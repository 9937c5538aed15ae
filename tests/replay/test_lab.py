"""Replay of a bag holding only the lab's topics, written with rosbags from one of logs/."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
import pytest

from hil.adapters.frames import ArenaTransform
from hil.bag.run_data import load_run
from hil.commands import replay
from hil.core.samples import Frame, PoseSample
from hil.replay.controllers import ScenarioCache
from hil.replay.lab import FLEW_SHARE, lab_topics, load_lab_config, pose_map
from hil.replay.options import ReplayOptions
from hil.replay.regression import Status
from hil.replay.replayer import replay_log
from tests.bag.bag_streams import tree_digest
from tests.replay.lab_bag import write_lab_bag

ROOT = Path(__file__).resolve().parents[2]
LOG = ROOT / "logs" / "coarse-high-seed2"
SCENARIO = "coarse"
TRANSFORM = ArenaTransform(origin_north_m=2.0, origin_east_m=-1.5, yaw_rad=0.4)
CONFIG = f"""
scenario = "{SCENARIO}"
[ros.topics]
pose = "/tank/pose"
[ros.transform]
origin_north_m = {TRANSFORM.origin_north_m}
origin_east_m = {TRANSFORM.origin_east_m}
yaw_rad = {TRANSFORM.yaw_rad}
"""


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Lab bags converted from LOG: as the lab records, with hil's types, without parts."""
    root = tmp_path_factory.mktemp("lab")
    return {
        "lab": write_lab_bag(LOG, root / "lab"),
        "hil_types": write_lab_bag(LOG, root / "hil_types", native=False),
        "no_command": write_lab_bag(
            LOG, root / "no_command", drop=["/voyager/control/velocity/command"]
        ),
        "no_odom": write_lab_bag(LOG, root / "no_odom", drop=["/voyager/measurement/odom"]),
        "no_pose": write_lab_bag(LOG, root / "no_pose", drop=["/voyager/measurement/pose"]),
    }


def run_replay(*argv: str) -> int:
    parser = argparse.ArgumentParser()
    replay.add_arguments(parser)
    return replay.run(parser.parse_args(list(argv)))


def test_pose_map_is_the_arena_transform_vectorized() -> None:
    rng = np.random.default_rng(3)
    transform = ArenaTransform(1.0, -2.0, 0.7, 0.1, -0.05, 0.2)
    lab = np.column_stack([rng.uniform(-5, 5, 50), rng.uniform(-5, 5, 50), rng.uniform(-3, 3, 50)])
    one = [
        transform.to_arena(PoseSample(0, float(n), float(e), float(y), Frame.LAB_NED))
        for n, e, y in lab
    ]
    expected = np.array([[p.x_m, p.y_m, p.yaw_rad] for p in one])
    got = pose_map(transform)(lab)
    np.testing.assert_allclose(got[:, :2], expected[:, :2], atol=1e-12)
    np.testing.assert_allclose(np.cos(got[:, 2] - expected[:, 2]), 1.0, atol=1e-12)


@pytest.mark.parametrize("kind", ["lab", "hil_types"])
def test_lab_bag_loads_the_streams_hil_recorded(bags: dict[str, Path], kind: str) -> None:
    before = tree_digest(bags[kind])
    hil = load_run(LOG)
    lab = load_run(bags[kind], lab_topics())
    assert lab.lab_only
    assert not hil.lab_only
    assert not lab.decisions
    assert not lab.layouts
    for name in ("pose", "imu", "estimate", "reference", "force"):
        ours, theirs = getattr(hil, name), getattr(lab, name)
        np.testing.assert_array_equal(ours.t_ns, theirs.t_ns)
        np.testing.assert_allclose(theirs.values, ours.values, atol=1e-9)
    # The azimuths come back as magnitude and angle: the same thrust vector.
    np.testing.assert_array_equal(lab.thrusters.t_ns, hil.thrusters.t_ns)
    h, v = hil.thrusters.values, lab.thrusters.values
    np.testing.assert_allclose(v[:, 0], h[:, 0], atol=1e-12)
    for mag, ang in ((1, 3), (2, 4)):
        np.testing.assert_allclose(v[:, mag] * np.cos(v[:, ang]), h[:, mag] * np.cos(h[:, ang]),
                                   atol=1e-9)
        np.testing.assert_allclose(v[:, mag] * np.sin(v[:, ang]), h[:, mag] * np.sin(h[:, ang]),
                                   atol=1e-9)
    assert any("per-thruster" in note for note in lab.notes)
    assert tree_digest(bags[kind]) == before


def test_lab_poses_in_the_lab_frame_map_back_through_the_config(
    tmp_path: Path, bags: dict[str, Path]
) -> None:
    bag = write_lab_bag(LOG, tmp_path / "moved", transform=TRANSFORM)
    config = tmp_path / "vessel.toml"
    config.write_text(CONFIG.replace("/tank/pose", "/voyager/measurement/pose"))
    topics_, _ = load_lab_config(config)
    back = load_run(bag, topics_)
    hil = load_run(LOG)
    np.testing.assert_allclose(back.pose.values[:, :2], hil.pose.values[:, :2], atol=1e-9)
    np.testing.assert_allclose(np.cos(back.pose.values[:, 2] - hil.pose.values[:, 2]), 1.0,
                               atol=1e-12)
    # Without the transform the poses stay where the lab saw them: far from the arena's.
    as_is = load_run(bag, lab_topics())
    assert np.abs(as_is.pose.values[:, :2] - hil.pose.values[:, :2]).max() > 1.0
    assert any("[ros.transform]" in note for note in back.notes)


def test_the_stack_rerun_on_a_lab_bag_takes_the_recorded_decisions(
    bags: dict[str, Path], caches: ScenarioCache
) -> None:
    hil = load_run(LOG)
    report = replay_log(
        bags["lab"], ReplayOptions(scenario=SCENARIO, intervals=True), caches
    )
    assert report.status is Status.PASS, report
    statuses = {c.name: c.status for c in report.checks}
    assert statuses == {
        "decisions": Status.SKIP,
        "stack": Status.PASS,
        "tracking": Status.PASS,
        "contract": Status.PASS,
    }
    stack = report.check("stack")
    assert stack.metrics["flown_share"] >= FLEW_SHARE
    assert len(stack.findings) == len(report.replayed) == stack.metrics["decisions"]
    # Same pose and IMU through the same stack: the decisions the recording took.
    recorded = {(d.t_ns, d.chosen_index) for d in hil.decisions}
    again = {(d.t_ns, d.chosen_index) for d in report.replayed}
    assert len(recorded & again) >= 0.9 * len(recorded)
    assert len(report.intervals) == len(report.replayed)
    assert all(i.status is Status.PASS for i in report.intervals)
    assert any("not judged without hil's topics" in note for note in report.notes)
    # The tracking figures are the recording's: the bag's commands against its odometry.
    tracking = report.check("tracking")
    assert "odometry" in tracking.summary
    assert tracking.metrics["samples"] > 100


def test_what_a_lab_bag_lacks_is_said_not_judged(
    bags: dict[str, Path], caches: ScenarioCache
) -> None:
    options = ReplayOptions(scenario=SCENARIO, intervals=True)
    no_command = replay_log(bags["no_command"], options, caches)
    assert no_command.status is Status.PASS
    assert no_command.check("tracking").status is Status.SKIP
    assert "no velocity command" in no_command.check("tracking").summary
    assert no_command.check("contract").status is Status.SKIP
    assert all(i.status is Status.SKIP for i in no_command.intervals)
    no_odom = replay_log(bags["no_odom"], options, caches)
    tracking = no_odom.check("tracking")
    assert tracking.status is Status.PASS
    assert "re-run estimate" in tracking.summary
    assert math.isfinite(tracking.metrics["rms"][0])


def test_lab_bag_errors_are_one_clear_line(
    bags: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    assert run_replay(str(bags["lab"])) == 2
    out, err = capsys.readouterr()
    assert "pass --scenario" in err
    assert "Traceback" not in out + err
    assert run_replay("--scenario", SCENARIO, str(bags["no_pose"])) == 2
    out, err = capsys.readouterr()
    assert "no pose on '/voyager/measurement/pose'" in err
    assert "Traceback" not in out + err


def test_replay_command_on_a_lab_bag_with_config_jsonl_and_rrd(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    renamed = write_lab_bag(
        LOG, tmp_path / "renamed", transform=TRANSFORM,
        rename={"/voyager/measurement/pose": "/tank/pose"},
    )
    config = tmp_path / "vessel.toml"
    config.write_text(CONFIG)
    jsonl = tmp_path / "out.jsonl"
    code = run_replay(
        "--scenario", SCENARIO, "--config", str(config), "--jsonl", str(jsonl),
        "--rerun", str(tmp_path / "rrd"), str(renamed),
    )
    out, err = capsys.readouterr()
    assert code == 0, out + err
    assert "[   ok] stack: re-run on the bag's pose and IMU" in out
    assert "decision at" in out
    assert "not judged without hil's topics" in out
    lines = [json.loads(line) for line in jsonl.read_text().splitlines()]
    assert lines[-1]["type"] == "verdict"
    assert lines[-1]["exit_code"] == 0
    intervals = [line for line in lines if line["type"] == "interval"]
    assert intervals
    assert {"chosen_index", "tube_contained", "tracking_rms", "verdict"} <= set(intervals[0])
    rrd = tmp_path / "rrd" / "renamed.replay.rrd"
    assert rrd.stat().st_size > 10_000
