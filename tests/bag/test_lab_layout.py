"""A hil bag as the lab's tools read it: the lab's topics in the lab's types and frames,
hil's own data under /hil, /tf_static, and rosbag2's metadata record in every split."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
from ruamel.yaml import YAML

from hil.bag import topics
from hil.bag.lab_frame import LabFrame
from hil.bag.metadata import read_metadata
from hil.bag.recorder import Recorder, RecorderConfig
from hil.bag.run_data import load_run
from hil.bag.run_info import RunInfo
from hil.core.arena_frame import ArenaTransform
from hil.core.geometry import quaternion_yaw
from hil.core.qtm_sample import QtmSample
from hil.core.samples import PoseSample, ThrusterCommand, VelocityReference

TRANSFORM = ArenaTransform(1.5, -2.0, 0.4, 0.12, -0.03, 0.05)
LAB = LabFrame(TRANSFORM, "world_ned")
MS = 1_000_000
N = 30
LAB_TYPES = {
    topics.POSE: "geometry_msgs/msg/PoseWithCovarianceStamped",
    topics.VELOCITY_COMMAND: "geometry_msgs/msg/Twist",
    topics.FORCE_COMMAND: "geometry_msgs/msg/Wrench",
    topics.THRUSTER_TUNNEL: "geometry_msgs/msg/Wrench",
    topics.THRUSTER_PORT: "geometry_msgs/msg/Wrench",
    topics.THRUSTER_STARBOARD: "geometry_msgs/msg/Wrench",
    topics.THRUSTERS: "hil_msgs/msg/ThrusterCommands",
    topics.TF_STATIC: "tf2_msgs/msg/TFMessage",
    topics.HIL_POSE: "geometry_msgs/msg/PoseWithCovarianceStamped",
    topics.HIL_VELOCITY_COMMAND: "geometry_msgs/msg/TwistStamped",
    topics.HIL_FORCE_COMMAND: "geometry_msgs/msg/WrenchStamped",
    topics.HIL_ODOM: "nav_msgs/msg/Odometry",
    topics.QTM_6D: "hil_msgs/msg/Qtm6D",
}


def _poses() -> list[PoseSample]:
    return [PoseSample(i * 10 * MS, 0.5 + 0.01 * i, -0.2, 0.3 - 0.02 * i) for i in range(N)]


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("lab") / "run"
    config = RecorderConfig(split_s=1e9, flush_s=1e9, threaded=False)
    with Recorder(path, RunInfo.current("coarse"), config, lab=LAB) as rec:
        for i, pose in enumerate(_poses()):
            rec.pose(pose)
            rec.velocity_reference(pose.t_ns, np.array([0.1, 0.0, -0.05]))
            rec.force(pose.t_ns, np.array([1.0, 0.5, -0.25]))
            rec.estimate(pose.t_ns, np.array([pose.x_m, pose.y_m, pose.yaw_rad]), np.zeros(3))
            rec.thrusters(ThrusterCommand(pose.t_ns, 0.1, 0.2, 0.3, 1.0, -1.0))
            rec.record(QtmSample(pose.t_ns, 5_000 + i, 100 + i, 1, "2", (1.0, 2.0, 3.0),
                                 (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0), drops=i // 10))
        rec.flush()
        rec._bag.close_split()  # type: ignore[union-attr]  # a second split
        rec.pose(PoseSample(N * 10 * MS, 0.0, 0.0, 0.0))
    return path


def _read(where: Path) -> dict[str, list[tuple[str, Any]]]:
    out: dict[str, list[tuple[str, Any]]] = {}
    with AnyReader([where], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        for connection, _, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            out.setdefault(connection.topic, []).append((connection.msgtype, msg))
    return out


@pytest.mark.parametrize("alone", [False, True], ids=["directory", "first mcap alone"])
def test_the_lab_topics_hold_the_lab_types_and_frames(bag: Path, alone: bool) -> None:
    got = _read(bag / "run_0.mcap" if alone else bag)
    assert {t: {m for m, _ in msgs} for t, msgs in got.items()} == {
        t: {m} for t, m in LAB_TYPES.items()
    }
    lab_poses = [msg for _, msg in got[topics.POSE]]
    for pose, msg in zip(_poses(), lab_poses, strict=False):
        want = TRANSFORM.to_lab(pose)  # the pose the lab's mocap driver would have sent
        assert msg.header.frame_id == "world_ned"
        p = msg.pose.pose
        assert p.position.x == pytest.approx(want.x_m, abs=1e-12)
        assert p.position.y == pytest.approx(want.y_m, abs=1e-12)
        yaw = quaternion_yaw(p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w)
        assert math.remainder(yaw - want.yaw_rad, math.tau) == pytest.approx(0.0, abs=1e-12)
    assert {msg.header.frame_id for _, msg in got[topics.HIL_POSE]} == {"arena"}
    twist = got[topics.VELOCITY_COMMAND][0][1]
    assert (twist.linear.x, twist.linear.y, twist.angular.z) == (0.1, 0.0, -0.05)
    wrench = got[topics.FORCE_COMMAND][0][1]
    assert (wrench.force.x, wrench.force.y, wrench.torque.z) == (1.0, 0.5, -0.25)


def test_tf_static_holds_world_ned_to_arena(bag: Path) -> None:
    got = _read(bag)
    assert len(got[topics.TF_STATIC]) == 2  # one at the start of each split
    (_, msg), _ = got[topics.TF_STATIC]
    frames = {(t.header.frame_id, t.child_frame_id): t.transform for t in msg.transforms}
    arena = frames[("world_ned", "arena")]
    assert (arena.translation.x, arena.translation.y) == (1.5, -2.0)
    r = arena.rotation
    assert quaternion_yaw(r.x, r.y, r.z, r.w) == pytest.approx(0.4, abs=1e-12)
    body = frames[("mocap_body", "body")]
    assert (body.translation.x, body.translation.y) == (0.12, -0.03)
    # hil reads it back as the transform it recorded with.
    frame = load_run(bag).lab_frame
    assert frame is not None
    assert frame.frame_id == "world_ned"
    assert np.allclose(
        [getattr(frame.transform, f) for f in TRANSFORM.__slots__],
        [getattr(TRANSFORM, f) for f in TRANSFORM.__slots__], atol=1e-12)  # fmt: skip


def test_every_split_carries_rosbag2s_metadata_record(bag: Path) -> None:
    listed = read_metadata(bag / "metadata.yaml")
    for name in ("run_0.mcap", "run_1.mcap"):
        with (bag / name).open("rb") as stream:
            reader = make_reader(stream)
            records = list(reader.iter_metadata())
            summary = reader.get_summary()
        assert summary is not None
        assert [i.name for i in summary.metadata_indexes] == ["rosbag2"]
        ((record),) = records
        assert record.name == "rosbag2"
        assert record.metadata["ROS_DISTRO"] == "jazzy"
        info = YAML(typ="safe").load(record.metadata["serialized_metadata"])
        assert info["version"] == 9
        assert info["storage_identifier"] == "mcap"
        assert info["ros_distro"] == "jazzy"
        assert name in info["relative_file_paths"]
        assert info["custom_data"]["hil_format"] == "3"
        assert {t["topic_metadata"]["name"] for t in info["topics_with_message_count"]} <= set(
            LAB_TYPES
        )
    # The last split's record is the bag's metadata.yaml, as rosbag2 writes it.
    assert info == listed


def test_the_run_loader_reads_hils_own_topics(bag: Path) -> None:
    run = load_run(bag)
    poses = _poses()
    assert np.allclose(run.pose.values[:N], [[p.x_m, p.y_m, p.yaw_rad] for p in poses])
    assert run.reference.values.tolist()[0] == [0.1, 0.0, -0.05]
    assert len(run.reference) == len(run.force) == len(run.estimate) == N
    assert len(run.qtm) == N
    assert run.qtm[-1].drops == 2
    assert run.notes == ()  # nothing read at log times or mapped: hil's stamped copies


def test_velocity_reference_without_stamp_time_is_refused_before_writing(tmp_path: Path) -> None:
    with Recorder(tmp_path / "run", lab=LAB) as rec, pytest.raises(ValueError, match="time"):
        rec.record(VelocityReference(-1, 0.0, 0.0, 0.0))
