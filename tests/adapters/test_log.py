"""The log backend: a loaded run served through the adapters against a simulated clock."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.adapters.interfaces import ThrusterSinkError
from hil.adapters.log import (
    CapturingThrusterSink,
    LogConfig,
    LogWorld,
    thruster_failures_ns,
)
from hil.bag.messages import Record
from hil.bag.recorder import RecorderConfig
from hil.bag.run_data import load_run
from hil.bag.run_info import RunInfo
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


def test_samples_are_delivered_after_their_delay_in_stamp_order(bag: Path) -> None:
    world = LogWorld(load_run(bag), LogConfig(pose_delay_ns=10 * MS, imu_delay_ns=0))
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
    world = LogWorld(load_run(bag))
    assert world.obstacles.latest().obstacles == (O1,)
    world.clock.sleep_until(99 * MS)
    assert world.obstacles.latest().t_ns == 0
    world.clock.sleep_until(100 * MS)
    assert world.obstacles.latest().obstacles[0].x_min_m == pytest.approx(1.85)


def test_sink_captures_commands_and_fails_where_the_recording_failed(bag: Path) -> None:
    world = LogWorld(load_run(bag))
    world.thrusters.send(ThrusterCommand(100 * MS, 0.5, 0.1, -0.1, 1.0, -1.0))
    with pytest.raises(ThrusterSinkError, match="t=150000000 ns"):
        world.thrusters.send(ThrusterCommand.zero(150 * MS))
    t, values = world.thrusters.as_array()
    assert t.tolist() == [100 * MS]
    assert values.shape == (1, 5)
    assert values[0].tolist() == [0.5, 0.1, -0.1, 1.0, -1.0]
    assert CapturingThrusterSink().as_array()[1].shape == (0, 5)


def test_world_without_layout_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "no_layout"
    write_bag(path, RunInfo(), [PoseSample(0, 0.0, 0.0, 0.0)], CONFIG)
    with pytest.raises(ValueError, match="no obstacle layout"):
        LogWorld(load_run(path))


def test_log_config_refuses_negative_delay() -> None:
    with pytest.raises(ValueError, match="pose_delay_ns"):
        LogConfig(pose_delay_ns=-1)


def test_the_recorded_thruster_failures_are_the_failure_events(bag: Path) -> None:
    assert thruster_failures_ns(load_run(bag)) == frozenset({150 * MS})
