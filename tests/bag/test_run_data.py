"""The one loader of a recorded run, and its rule for bad, duplicate and late messages."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np
import pytest

from hil.bag import topics
from hil.bag.errors import BagNotFoundError, FrameError, NotAHilRunError
from hil.bag.messages import Record, encode
from hil.bag.recorder import RecorderConfig
from hil.bag.repairs import RepairKind
from hil.bag.run_data import FIELDS, load_run
from hil.bag.run_info import RunInfo
from hil.commands.record_suite import write_bag
from hil.core.records import Decision, Event, EventLevel, StateEstimate
from hil.core.samples import (
    Frame,
    ImuSample,
    ObstacleLayout,
    PoseSample,
    VelocityReference,
)
from hil.core.shapes import Rect
from tests.bag.bag_streams import write_raw_mcap

MS = 1_000_000
CONFIG = RecorderConfig(split_s=1e9, flush_s=1e9, threaded=False)
O1 = Rect(1.75, 2.25, -3.0, 0.0)


def _nan_pose(t_ns: int) -> bytes:
    _, (_, good) = encode(PoseSample(t_ns, 1.0, 2.0, 0.5))  # the arena pose, as format 2 held
    bad = bytearray(good)
    offset = len(good) - 43 * 8  # x: the first of the 43 doubles after the header
    bad[offset : offset + 8] = struct.pack("<d", math.nan)
    return bytes(bad)


def _mcap(path: Path, messages: list[tuple[int, Record | tuple[str, bytes]]]) -> Path:
    """Write a bare MCAP: each (log time ns, record or (topic, payload)) in the given order."""
    return write_raw_mcap(path, [
        (topic, log_ns, payload)
        for log_ns, item in messages
        for topic, payload in (encode(item) if not isinstance(item, tuple) else [item])
    ])  # fmt: skip


def _pose(k: int) -> PoseSample:
    return PoseSample(10 * MS * k, 1.0 + 0.01 * k, 2.0, 0.5)


def _decision(t_ns: int, chosen: int) -> Decision:
    return Decision.from_arrays(
        t_ns, [0, 0, 0], 1, 5.0, True, [[0.1, 0, 0]], [chosen], chosen, 1, "h"
    )


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    """Poses and IMU at 100 Hz for 0.2 s, two layouts, a thruster failure event."""
    records: list[Record] = [ObstacleLayout(0, (O1,))]
    for k in range(20):
        records += [_pose(k), ImuSample(10 * MS * k, 0.0, 0.1, 0.01 * k)]
    records.append(ObstacleLayout(100 * MS, (O1.translate(0.1, 0.0),)))
    records.append(Event(150 * MS, EventLevel.ERROR, "thruster_failure", "link down"))
    records.sort(key=lambda r: r.t_ns)
    path = tmp_path / "run"
    write_bag(path, RunInfo("coarse", "h", 0, backend="sim"), records, CONFIG)
    return path


def test_a_clean_run_loads_every_stream_and_repairs_nothing(bag: Path) -> None:
    run = load_run(bag)
    assert run.pose.values.shape == (20, len(FIELDS[topics.POSE]))
    assert run.pose.t_ns[:3].tolist() == [0, 10 * MS, 20 * MS]
    assert run.imu.values[5].tolist() == pytest.approx([0.0, 0.1, 0.05])
    assert [x.t_ns for x in run.layouts] == [0, 100 * MS]
    assert run.layouts[1].as_obstacle_layout().obstacles[0].x_min_m == pytest.approx(1.85)
    assert [e.code for e in run.events] == ["thruster_failure"]
    assert run.last_stamp_ns == 190 * MS
    assert (run.repairs, run.skipped, run.warnings) == ((), (), ())


def test_the_rule_on_a_bag_with_bad_duplicate_and_late_messages(tmp_path: Path) -> None:
    """One bag, every case: all samples kept once, in stamp order, each repair reported."""
    late = _pose(3)  # recorded after the pose of 50 ms: arrives late
    messages: list[tuple[int, Record | tuple[str, bytes]]] = [
        (0, ObstacleLayout(0, (O1,))),
        (0, _pose(0)),
        (10 * MS, _pose(1)),
        (10 * MS, _pose(1)),  # exact duplicate
        (20 * MS, _pose(2)),
        (40 * MS, (topics.HIL_POSE, _nan_pose(40 * MS))),  # bad: NaN
        (50 * MS, _pose(5)),
        (55 * MS, late),
        (60 * MS, PoseSample(60 * MS, 9.0, 9.0, 0.0)),
        (60 * MS, PoseSample(60 * MS, 8.0, 8.0, 0.0)),  # same stamp, other values: kept
        (70 * MS, _decision(70 * MS, 1)),
        (70 * MS, _decision(70 * MS, 1)),  # duplicated decision
        (80 * MS, _decision(80 * MS, 2)),
        (85 * MS, _decision(75 * MS, 3)),  # late decision
        (90 * MS, Event(90 * MS, EventLevel.INFO, "a", "one")),
        (90 * MS, Event(90 * MS, EventLevel.INFO, "b", "two")),  # two events, one tick
    ]
    run = load_run(_mcap(tmp_path / "imperfect.mcap", messages))
    assert run.pose.t_ns.tolist() == [0, 10 * MS, 20 * MS, 30 * MS, 50 * MS, 60 * MS, 60 * MS]
    assert run.pose.values[3].tolist() == pytest.approx([late.x_m, late.y_m, late.yaw_rad])
    assert run.pose.values[5:, 0].tolist() == [9.0, 8.0]  # recorded order within a stamp
    assert np.isfinite(run.pose.values).all()
    assert [(d.t_ns, d.chosen_index) for d in run.decisions] == [
        (70 * MS, 1),
        (75 * MS, 3),
        (80 * MS, 2),
    ]
    assert [e.code for e in run.events] == ["a", "b"]
    found = {(r.topic, r.kind): r for r in run.repairs}
    assert set(found) == {
        (topics.POSE, RepairKind.BAD),
        (topics.POSE, RepairKind.REORDERED),
        (topics.POSE, RepairKind.DUPLICATE),
        (topics.POSE, RepairKind.SAME_STAMP),
        (topics.DECISION, RepairKind.DUPLICATE),
        (topics.DECISION, RepairKind.REORDERED),
    }
    assert (found[topics.POSE, RepairKind.BAD].count, found[topics.POSE, RepairKind.BAD].t_ns) == (
        1,
        40 * MS,
    )
    assert found[topics.POSE, RepairKind.REORDERED].t_ns == 30 * MS
    assert found[topics.POSE, RepairKind.DUPLICATE].t_ns == 10 * MS
    assert found[topics.DECISION, RepairKind.DUPLICATE].count == 1
    assert [(s.topic, s.t_ns) for s in run.skipped] == [(topics.HIL_POSE, 40 * MS)]
    assert len(run.warnings) == len(run.repairs)
    assert any("go back in time" in w and "t=30000000 ns" in w for w in run.warnings)
    assert any("dropped 1 duplicated" in w and "t=10000000 ns" in w for w in run.warnings)
    assert any("skipped 1 message" in w and "t=40000000 ns" in w for w in run.warnings)


def test_poses_outside_the_arena_frame_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "ned"
    # A log of hil format 2's layout (no /hil/pose) whose pose topic holds the lab's frame.
    (lab_pose, payload), _ = encode(PoseSample(0, 1.0, 2.0, 0.0, Frame.LAB_NED))
    _mcap(path, [(0, (lab_pose, payload))])
    with pytest.raises(FrameError, match="'world_ned'"):
        load_run(path)


def test_bad_paths_and_foreign_logs_raise_bag_errors(tmp_path: Path) -> None:
    with pytest.raises(BagNotFoundError, match="does not exist"):
        load_run(tmp_path / "nope")
    other = tmp_path / "other"
    write_bag(other, RunInfo(), [], CONFIG)
    with pytest.raises(NotAHilRunError, match="not a hil run"):
        load_run(other)


def test_a_run_without_motion_loads_but_cannot_be_drawn(tmp_path: Path) -> None:
    path = tmp_path / "events_only"
    write_bag(path, RunInfo(), [Event(0, EventLevel.INFO, "start", "")], CONFIG)
    run = load_run(path)
    assert len(run.pose) == 0
    with pytest.raises(NotAHilRunError, match="nothing to show"):
        run.require_motion()


def test_tracking_error_joins_each_estimate_with_the_reference_in_force(
    tmp_path: Path,
) -> None:
    records: list[Record] = [
        StateEstimate(t, 0.0, 0.0, 0.0, 0.1 * k, 0.0, 0.01 * k)
        for k, t in enumerate(range(0, 100 * MS, 10 * MS))
    ]
    records += [VelocityReference(25 * MS, 0.2, 0.0, 0.0), VelocityReference(55 * MS, 0.5, 0, 0.1)]
    records.sort(key=lambda r: r.t_ns)
    path = tmp_path / "tracking"
    write_bag(path, RunInfo(), records, CONFIG)
    error = load_run(path).tracking_error()
    assert error.t_ns.tolist() == list(range(30 * MS, 100 * MS, 10 * MS))
    held = np.where(error.t_ns < 55 * MS, 0.2, 0.5)
    k = error.t_ns // (10 * MS)
    np.testing.assert_allclose(error.error[:, 0], 0.1 * k - held)
    np.testing.assert_allclose(error.error[:, 2], 0.01 * k - np.where(k < 6, 0.0, 0.1))
