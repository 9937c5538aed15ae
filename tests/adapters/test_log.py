"""The log backend: recorded samples served in recorded order against a simulated clock."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np
import pytest
from mcap.writer import Writer as McapWriter

from hil.adapters.interfaces import ThrusterSinkError
from hil.adapters.log import (
    CapturingThrusterSink,
    LogConfig,
    LogWorld,
    read_log,
)
from hil.bag import topics
from hil.bag import typestore as ts
from hil.bag.errors import BagNotFoundError, NotAHilRunError
from hil.bag.messages import Record, encode
from hil.bag.recorder import RecorderConfig, RunInfo
from hil.commands.record_suite import write_bag
from hil.core.records import Event, EventLevel
from hil.core.samples import (
    ImuSample,
    ObstacleLayout,
    PoseSample,
    ThrusterCommand,
)
from hil.core.shapes import Rect

MS = 1_000_000
CONFIG = RecorderConfig(split_s=1e9, flush_s=1e9, threaded=False)
O1 = Rect(1.75, 2.25, -3.0, 0.0)


def _records() -> list[Record]:
    """Poses and IMU at 100 Hz for 0.2 s, two layouts, a thruster failure event."""
    out: list[Record] = [ObstacleLayout(0, (O1,))]
    for k in range(20):
        t = 10 * MS * k
        out.append(PoseSample(t, 1.0 + 0.01 * k, 2.0, 0.5))
        out.append(ImuSample(t, 0.0, 0.1, 0.01 * k))
    out.append(ObstacleLayout(100 * MS, (O1.translate(0.1, 0.0),)))
    out.append(Event(150 * MS, EventLevel.ERROR, "thruster_failure", "link down"))
    out.sort(key=lambda r: r.t_ns)
    return out


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    path = tmp_path / "run"
    write_bag(path, RunInfo("coarse", "h", 0, backend="sim"), _records(), CONFIG)
    return path


def test_read_log_gives_columns_and_records(bag: Path) -> None:
    run = read_log(bag)
    assert run.poses.values.shape == (20, 3)
    assert run.poses.t_ns[:3].tolist() == [0, 10 * MS, 20 * MS]
    assert run.imus.values[5].tolist() == pytest.approx([0.0, 0.1, 0.05])
    assert [x.t_ns for x in run.layouts] == [0, 100 * MS]
    assert run.thruster_failures_ns() == frozenset({150 * MS})
    assert run.end_ns == 190 * MS
    assert run.warnings == ()


def test_samples_are_delivered_after_their_delay_in_recorded_order(bag: Path) -> None:
    world = LogWorld(read_log(bag), LogConfig(pose_delay_ns=10 * MS, imu_delay_ns=0))
    assert world.pose.poll() == []
    assert world.imu.poll() == []
    world.clock.sleep_until(50 * MS)
    poses, imus = world.pose.poll(), world.imu.poll()
    # Delivered when stamp + delay < now, as the simulated world delivers them.
    assert [p.t_ns for p in poses] == [0, 10 * MS, 20 * MS, 30 * MS]
    assert [i.t_ns for i in imus] == [0, 10 * MS, 20 * MS, 30 * MS, 40 * MS]
    assert poses[1] == PoseSample(10 * MS, 1.01, 2.0, 0.5)
    assert world.pose.poll() == []  # each sample once
    world.clock.sleep_until(1000 * MS)
    assert len(world.pose.poll()) == 16


def test_obstacles_follow_the_recorded_layouts(bag: Path) -> None:
    world = LogWorld(read_log(bag))
    assert world.obstacles.latest().obstacles == (O1,)
    world.clock.sleep_until(99 * MS)
    assert world.obstacles.latest().t_ns == 0
    world.clock.sleep_until(100 * MS)
    assert world.obstacles.latest().obstacles[0].x_min_m == pytest.approx(1.85)


def test_sink_captures_commands_and_fails_where_the_recording_failed(bag: Path) -> None:
    world = LogWorld(read_log(bag))
    world.thrusters.send(ThrusterCommand(100 * MS, 0.5, 0.1, -0.1, 1.0, -1.0))
    with pytest.raises(ThrusterSinkError, match="t=150000000 ns"):
        world.thrusters.send(ThrusterCommand.zero(150 * MS))
    t, values = world.thrusters.as_array()
    assert t.tolist() == [100 * MS]
    assert values.shape == (1, 5)
    assert values[0].tolist() == [0.5, 0.1, -0.1, 1.0, -1.0]
    assert CapturingThrusterSink().as_array()[1].shape == (0, 5)


def _copy_raw(
    src: Path, dst: Path, edit: dict[int, bytes | None], extra: int | None = None
) -> Path:
    """Rewrite src's one MCAP split into dst as a bare .mcap, editing pose payloads by index.

    `edit` maps the index of a pose message to a new payload (None drops it);
    `extra` repeats the pose with that index (a duplicate).
    """
    from hil.bag.reader import BagReader

    out = dst / "edited.mcap"
    with BagReader(src) as reader, out.open("wb") as stream:
        writer = McapWriter(stream)
        writer.start(profile="ros2", library="test")
        channels: dict[str, int] = {}
        n = 0
        for raw in reader.messages():
            if raw.topic not in channels:
                schema = writer.register_schema(
                    raw.msgtype, "ros2msg", ts.schema_text(raw.msgtype).encode()
                )
                channels[raw.topic] = writer.register_channel(raw.topic, "cdr", schema)
            payload: bytes | None = raw.data
            repeat = 1
            if raw.topic == topics.POSE:
                payload = edit.get(n, raw.data)
                repeat = 2 if n == extra else 1
                n += 1
            for _ in range(repeat if payload is not None else 0):
                assert payload is not None
                writer.add_message(channels[raw.topic], raw.t_ns, payload, raw.t_ns)
        writer.finish()  # type: ignore[no-untyped-call]
    return out


def test_duplicates_are_dropped_with_a_warning(bag: Path, tmp_path: Path) -> None:
    run = read_log(_copy_raw(bag, tmp_path, {}, extra=3))
    assert len(run.poses) == 20
    assert any("dropped 1 duplicated" in w and "t=30000000 ns" in w for w in run.warnings)


def test_stamps_going_back_are_served_in_recorded_order_with_a_warning(
    bag: Path, tmp_path: Path
) -> None:
    ((_, late),) = encode(PoseSample(5 * MS, 9.0, 9.0, 0.0))
    run = read_log(_copy_raw(bag, tmp_path, {3: late}))
    assert run.poses.t_ns[2:5].tolist() == [20 * MS, 5 * MS, 40 * MS]
    assert any("go back in time" in w and "t=5000000 ns" in w for w in run.warnings)
    world = LogWorld(run, LogConfig(pose_delay_ns=0))
    world.clock.sleep_until(25 * MS)
    # The late-stamped sample is delivered with its predecessor, never before it.
    assert [p.t_ns for p in world.pose.poll()] == [0, 10 * MS, 20 * MS, 5 * MS]


def test_nan_message_is_skipped_with_a_warning(bag: Path, tmp_path: Path) -> None:
    ((_, good),) = encode(PoseSample(70 * MS, 1.07, 2.0, 0.5))
    bad = bytearray(good)
    offset = len(good) - 43 * 8  # x: the first of the 43 doubles after the header
    bad[offset : offset + 8] = struct.pack("<d", math.nan)
    run = read_log(_copy_raw(bag, tmp_path, {7: bytes(bad)}))
    assert 70 * MS not in run.poses.t_ns.tolist()
    assert len(run.poses) == 19
    assert np.isfinite(run.poses.values).all()
    assert any("skipped 1 message" in w and "t=70000000 ns" in w for w in run.warnings)


def test_bad_paths_raise_bag_errors(tmp_path: Path) -> None:
    with pytest.raises(BagNotFoundError, match="does not exist"):
        read_log(tmp_path / "nope")
    other = tmp_path / "other"
    write_bag(other, RunInfo(), [], CONFIG)
    with pytest.raises(NotAHilRunError, match="not a hil run"):
        read_log(other)


def test_world_without_layout_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "no_layout"
    write_bag(path, RunInfo(), [PoseSample(0, 0.0, 0.0, 0.0)], CONFIG)
    with pytest.raises(ValueError, match="no obstacle layout"):
        LogWorld(read_log(path))


def test_log_config_refuses_negative_delay() -> None:
    with pytest.raises(ValueError, match="pose_delay_ns"):
        LogConfig(pose_delay_ns=-1)
