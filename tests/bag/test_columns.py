"""A topic read as numpy columns holds exactly what reading it as samples gives."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np
import pytest

from hil.bag import topics
from hil.bag.columns import COLUMN_TYPES, Columns, to_columns
from hil.bag.errors import MessageDecodeError
from hil.bag.messages import encode
from hil.bag.reader import BagReader
from hil.bag.recorder import Recorder, RecorderConfig
from hil.core.samples import Frame, ImuSample, PoseSample
from tests.bag.bag_streams import one_of_each, write_raw_mcap


def _columns(reader: BagReader, topic: str) -> Columns:
    msgtype = {t.name: t.msgtype for t in reader.info.topics}[topic]
    return to_columns(topic, msgtype, list(reader.messages([topic])), reader.sample)


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    path = tmp_path / "run"
    with Recorder(path, config=RecorderConfig(threaded=False)) as recorder:
        for i in range(40):
            for record in one_of_each(1_000_000_000 + 10_000_000 * i, i):
                if not (isinstance(record, PoseSample) and record.frame is Frame.LAB_NED):
                    recorder.record(record)
    return path


def test_columns_equal_the_records(bag: Path) -> None:
    with BagReader(bag) as reader:
        checked = 0
        for info in reader.info.topics:
            if info.msgtype not in COLUMN_TYPES:
                continue
            columns = _columns(reader, info.name)
            records = [r for _, _, r in reader.records([info.name])]
            assert columns.t_ns.tolist() == [r.t_ns for r in records]
            for name, values in columns.fields.items():
                want = np.array([getattr(r, name) for r in records])
                tol = 1e-12 if name == "yaw_rad" else 0.0
                np.testing.assert_allclose(values, want, rtol=0, atol=tol)
            checked += 1
        assert checked == 7  # the pose in both frames, imu, estimate, commands, thrusters
    assert columns.stack(*list(columns.fields)[:2]).shape == (40, 2)


def test_topic_without_columns(bag: Path) -> None:
    with BagReader(bag) as reader, pytest.raises(MessageDecodeError, match="has no columns"):
        _columns(reader, topics.DECISION)


def _write(path: Path, payloads: list[bytes]) -> None:
    write_raw_mcap(path, [(topics.POSE, i, payload) for i, payload in enumerate(payloads)])


def _pose(i: int, frame: Frame = Frame.ARENA) -> bytes:
    # The arena pose is on /hil/pose; a lab-frame pose goes to the lab's topic as it is.
    payloads = dict(encode(PoseSample(i, float(i), 0.0, 0.0, frame)))
    return payloads[topics.HIL_POSE if frame is Frame.ARENA else topics.POSE]


def test_mixed_frames_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "mixed.mcap"
    _write(path, [_pose(0), _pose(1, Frame.LAB_NED)])
    with BagReader(path) as reader, pytest.raises(MessageDecodeError, match="mixes frames"):
        _columns(reader, topics.POSE)


def test_nan_is_named_not_returned(tmp_path: Path) -> None:
    path = tmp_path / "nan.mcap"
    bad = bytearray(_pose(1))
    offset = len(bad) - 43 * 8
    bad[offset : offset + 8] = struct.pack("<d", math.nan)
    _write(path, [_pose(0), bytes(bad), _pose(2)])
    with BagReader(path) as reader, pytest.raises(MessageDecodeError, match="at t=1 ns"):
        _columns(reader, topics.POSE)


def test_empty_topic(tmp_path: Path) -> None:
    bag = tmp_path / "run"
    with Recorder(bag) as recorder:
        recorder.record(ImuSample(1, 0.0, 0.0, 0.0))
    with BagReader(bag) as reader:
        assert _columns(reader, topics.IMU).fields["yaw_rate_radps"].tolist() == [0.0]
