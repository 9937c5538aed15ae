"""The recorder writes a bag that hil, rosbags and mcap_ros2 all read back equal."""

from __future__ import annotations

import math
import shutil
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader as RosbagsReader

from hil.bag import topics
from hil.bag.columnar import BULK_ENCODERS
from hil.bag.errors import RecorderClosedError, RecorderError, RecordValueError
from hil.bag.messages import Record, encode
from hil.bag.reader import BagReader
from hil.bag.recorder import Recorder, RecorderConfig
from hil.bag.run_info import RunInfo
from hil.bag.typestore import typestore
from hil.core.arena_frame import ArenaTransform
from hil.core.records import Decision, EventLevel, ForceCommand, StateEstimate
from hil.core.samples import ImuSample, ObstacleLayout, PoseSample, ThrusterCommand
from hil.core.shapes import Rect
from tests.bag.bag_streams import one_of_each
from tests.bag.reference_messages import reference_payloads

R = TypeVar("R", bound=Record)

RUN = RunInfo("scenarios/paper.toml", "sha256:abc", 7, "0.1.0", "deadbeef", "sim")


def expected_back(records: Sequence[R]) -> list[R]:
    """What reading hil's topics yields: everything, poses in the arena, in time order (stable).

    The recorder's lab frame is the identity here.
    """
    arena: list[R] = [
        ArenaTransform().to_arena(r) if isinstance(r, PoseSample) else r  # type: ignore[misc]
        for r in records
    ]
    return sorted(arena, key=lambda r: r.t_ns)


def streams(records: Sequence[Record]) -> dict[tuple[str, object], list[Record]]:
    """Group by stream: record type, and frame for poses; sorted keys."""
    out: dict[tuple[str, object], list[Record]] = {}
    for r in records:
        out.setdefault((type(r).__name__, str(getattr(r, "frame", ""))), []).append(r)
    return dict(sorted(out.items()))


def same(got: Record, want: Record) -> bool:
    if isinstance(want, PoseSample | StateEstimate):
        return (
            type(got) is type(want)
            and math.isclose(got.yaw_rad, want.yaw_rad, abs_tol=1e-12)
            and all(getattr(got, f) == getattr(want, f) for f in want.__slots__ if f != "yaw_rad")
        )
    return got == want


LAB_SIDE = frozenset({topics.POSE, topics.VELOCITY_COMMAND, topics.FORCE_COMMAND, topics.TF_STATIC})
"""The lab's topics hil fills beside its own (and /tf_static): no record of their own."""


@pytest.mark.parametrize("threaded", [True, False], ids=["threaded", "inline"])
def test_round_trip_every_stream(tmp_path: Path, records: list[Record], threaded: bool) -> None:
    bag = tmp_path / "run"
    with Recorder(bag, RUN, RecorderConfig(threaded=threaded)) as recorder:
        for record in records:
            recorder.record(record)
    assert recorder.files == ("run_0.mcap",)
    with BagReader(bag) as reader:
        # hil's own copies; the lab's topics (pose in its frame, unstamped commands) aside
        own = [t.name for t in reader.info.topics if t.name not in LAB_SIDE]
        got = [r for _, _, r in reader.records(own)]
        info = reader.info
    # Per stream, in time order (ties keep arrival order); streams interleave freely.
    want = streams(expected_back(records))
    assert list(want) == list(streams(got))
    for key, got_stream in streams(got).items():
        assert len(got_stream) == len(want[key])
        def order(r: Record) -> tuple[int, str]:  # ties in time: any order
            return r.t_ns, f"{getattr(r, 'x_m', 0.0):.6f}"

        for g, w in zip(sorted(got_stream, key=order), sorted(want[key], key=order), strict=True):
            assert same(g, w), (g, w)
    assert info.run == RUN
    assert info.problems == ()
    # poses and commands go to two topics, thrusters to four; one /tf_static per split
    assert info.message_count == sum(len(encode(r)) for r in records) + 1


def test_rosbags_reads_metadata_and_decodes_custom_types(
    tmp_path: Path, records: list[Record]
) -> None:
    bag = tmp_path / "run"
    with Recorder(bag, RUN) as recorder:
        for record in records:
            recorder.record(record)
    with RosbagsReader(bag) as plain:
        assert plain.storage.metadata.custom == RUN.custom_data()
        assert plain.message_count == sum(1 for _ in plain.messages())
    with AnyReader([bag]) as reader:
        counts: dict[str, int] = {}
        for connection, _, raw in reader.messages():
            msg: Any = reader.deserialize(raw, connection.msgtype)
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
            if connection.topic == topics.DECISION:
                assert msg.scenario_hash == "sha256:abc"
        assert counts[topics.DECISION] == 6
        assert set(counts) == set(topics.TOPIC_TYPES) - {topics.QTM_6D}  # no qtm backend


def test_mcap_ros2_decodes_every_message(tmp_path: Path, records: list[Record]) -> None:
    bag = tmp_path / "run"
    with Recorder(bag, RUN) as recorder:
        for record in records:
            recorder.record(record)
    decisions = [r for r in records if isinstance(r, Decision)]
    seen = []
    with (bag / "run_0.mcap").open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _, channel, message, msg in reader.iter_decoded_messages(log_time_order=True):
            assert (
                message.log_time == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
                if hasattr(msg, "header")
                else True
            )
            if channel.topic == topics.DECISION:
                seen.append((msg.x, msg.y, msg.psi, msg.cell, msg.value, list(msg.chosen_input)))
    assert seen == [
        (*d.state, d.cell, d.value, list(d.chosen_input)) for d in expected_back(decisions)
    ]


def test_splits_are_closed_and_listed(tmp_path: Path) -> None:
    bag = tmp_path / "run"
    config = RecorderConfig(split_s=0.05, flush_s=0.01)
    with Recorder(bag, RUN, config) as recorder:
        for i in range(40):
            recorder.record(ImuSample(i * 10_000_000, 0.0, 0.0, float(i)))
            time.sleep(0.005)
        time.sleep(0.1)
        listed_while_open = RosbagsReader(bag)
        listed_while_open.open()
        assert listed_while_open.message_count > 0  # closed splits readable mid-run
        listed_while_open.close()
    assert len(recorder.files) >= 2
    store = typestore()
    with RosbagsReader(bag) as plain:
        assert plain.message_count == 40 + len(recorder.files)  # one /tf_static per split
        imu = [c for c in plain.connections if c.topic == topics.IMU]
        msgs: list[Any] = [
            store.deserialize_cdr(raw, c.msgtype) for c, _, raw in plain.messages(imu)
        ]
        rates = [m.angular_velocity.z for m in msgs]
    assert sorted(rates) == [float(i) for i in range(40)]


def test_metadata_exists_from_the_start(tmp_path: Path) -> None:
    bag = tmp_path / "run"
    recorder = Recorder(bag, RUN)
    recorder.open()
    try:
        assert (bag / "metadata.yaml").is_file()
        with BagReader(bag) as reader:
            assert reader.info.message_count == 0
            assert reader.info.run == RUN
    finally:
        recorder.close()


def test_run_log_interface(tmp_path: Path) -> None:
    bag = tmp_path / "run"
    with Recorder(bag, RUN) as log:
        log.estimate(5, np.array([1.0, 2.0, 0.5]), np.array([0.1, 0.2, 0.3]))
        log.velocity_reference(5, np.array([0.1, 0.0, -0.1]))
        log.force(5, np.array([1.0, 2.0, 3.0]))
        log.event(6, EventLevel.ERROR, "no_winning_set", "layout leaves no winning set")
        log.thrusters(ThrusterCommand.zero(7))
    with BagReader(bag) as reader:
        got = {topic: record for topic, _, record in reader.records()}
    odom = got[topics.HIL_ODOM]
    assert isinstance(odom, StateEstimate)
    assert odom.yaw_rad == pytest.approx(0.5, abs=1e-12)
    assert odom.eta()[:2].tolist() == [1.0, 2.0]
    assert odom.nu().tolist() == [0.1, 0.2, 0.3]
    assert got[topics.HIL_FORCE_COMMAND] == ForceCommand(5, 1.0, 2.0, 3.0)
    assert got[topics.THRUSTERS] == ThrusterCommand.zero(7)


def test_record_before_open_and_after_close_is_refused(tmp_path: Path) -> None:
    recorder = Recorder(tmp_path / "run", RUN)
    with pytest.raises(RecorderClosedError, match="not open"):
        recorder.record(ImuSample(0, 0.0, 0.0, 0.0))
    recorder.open()
    recorder.close()
    with pytest.raises(RecorderClosedError, match="is closed"):
        recorder.record(ImuSample(0, 0.0, 0.0, 0.0))
    recorder.close()  # closing twice is harmless
    with pytest.raises(RecorderError, match="already opened"):
        recorder.open()


def test_existing_nonempty_directory_is_refused(tmp_path: Path) -> None:
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "notes.txt").write_text("keep me")
    with pytest.raises(RecorderError, match="not an empty directory"):
        Recorder(tmp_path / "run").open()
    assert (tmp_path / "run" / "notes.txt").read_text() == "keep me"


def test_bad_record_raises_before_anything_is_written(tmp_path: Path) -> None:
    bag = tmp_path / "run"
    with Recorder(bag, RUN) as recorder:
        recorder.record(ImuSample(1, 0.0, 0.0, 0.0))
        with pytest.raises(RecordValueError, match="cannot record 'dict'"):
            recorder.record({"t_ns": 2})  # type: ignore[arg-type]
        with pytest.raises(ValueError, match="non-finite"):
            recorder.velocity_reference(3, np.array([math.nan, 0.0, 0.0]))
        with pytest.raises(RecordValueError, match="non-finite"):
            recorder.estimate(3, np.array([0.0, math.inf, 0.0]), np.zeros(3))
        recorder.record(ImuSample(4, 0.0, 0.0, 1.0))
    with BagReader(bag) as reader:
        assert [t for _, t, _ in reader.records()] == [1, 4]


def test_bad_config_is_refused() -> None:
    with pytest.raises(RecordValueError, match="flush_s"):
        RecorderConfig(split_s=0.1, flush_s=0.5)


@pytest.mark.parametrize("threaded", [True, False], ids=["threaded", "inline"])
def test_write_failure_is_reported_not_swallowed(tmp_path: Path, threaded: bool) -> None:
    bag = tmp_path / "run"
    recorder = Recorder(bag, RUN, RecorderConfig(split_s=0.01, flush_s=0.01, threaded=threaded))
    recorder.open()
    recorder.record(ImuSample(1, 0.0, 0.0, 0.0))
    recorder.flush()
    shutil.rmtree(bag)  # the next split and metadata.yaml cannot be written
    time.sleep(0.02)

    def keep_recording() -> None:
        for i in range(2, 100):
            recorder.record(ImuSample(i, 0.0, 0.0, 0.0))
            recorder.flush()

    with pytest.raises(RecorderError, match="No such file or directory"):
        keep_recording()
    with pytest.raises(RecorderError, match="No such file or directory"):
        recorder.record(ImuSample(100, 0.0, 0.0, 0.0))
    with pytest.raises(RecorderError, match="failed"):
        recorder.close()


def test_bulk_encoders_equal_the_independent_reference() -> None:
    """Each stream written in bulk is what rosbags serializes from hand-built messages."""
    store = typestore()
    groups: dict[tuple[type, object], list[Record]] = {}
    for i in range(5):
        for r in one_of_each(1_000_000_000 + 7 * i, i):
            if type(r) in BULK_ENCODERS:
                groups.setdefault((type(r), getattr(r, "frame", None)), []).append(r)
    checked = 0
    for (kind, _), group in groups.items():
        for block in BULK_ENCODERS[kind](group):
            msgtype = topics.TOPIC_TYPES[block.topic]
            assert block.t_ns.tolist() == [r.t_ns for r in group]
            for row, record in zip(block.payloads, group, strict=True):
                (want,) = [p for t, p in reference_payloads(record) if t == block.topic]
                if block.topic in AZIMUTH_TOPICS:  # c (cos a, sin a): numpy's cos and sin
                    got_force: Any = store.deserialize_cdr(bytes(row), msgtype)
                    want_force: Any = store.deserialize_cdr(want, msgtype)
                    got_force, want_force = got_force.force, want_force.force
                    assert (got_force.x, got_force.y) == pytest.approx((want_force.x, want_force.y))
                else:
                    assert bytes(row) == want
                checked += 1
    # poses (arena and lab groups) and commands: two topics each, thrusters: four
    assert checked == 5 * (len(groups) + 7)


AZIMUTH_TOPICS = frozenset({topics.THRUSTER_PORT, topics.THRUSTER_STARBOARD})


def test_recorder_is_the_runtimes_run_log(tmp_path: Path) -> None:
    from hil.runtime.protocols import RunLog

    log: RunLog = Recorder(tmp_path / "run", RUN)  # mypy checks the interface
    assert isinstance(log, Recorder)
    log.open()
    log.pose(PoseSample(1, 0.0, 0.0, 0.0))
    log.imu(ImuSample(1, 0.0, 0.0, 0.0))
    log.obstacles(ObstacleLayout(1, (Rect(0.0, 1.0, 0.0, 1.0),)))
    log.close()
    with BagReader(tmp_path / "run") as reader:
        own = {t for t, _, _ in reader.records()}  # the lab's pose copy left out
        assert own == {topics.HIL_POSE, topics.IMU, topics.OBSTACLES}
