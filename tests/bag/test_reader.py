"""The reader describes and reads hil's and foreign logs, fails clearly, and never writes."""

from __future__ import annotations

import math
import shutil
import struct
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.writer import Writer as McapWriter

from hil.bag.errors import (
    BagError,
    BagFormatError,
    BagNotFoundError,
    MessageDecodeError,
    NotAHilRunError,
    ReplayError,
    SchemaError,
    UnsupportedBagError,
)
from hil.bag.messages import encode
from hil.bag.reader import BagReader, describe
from hil.bag.recorder import Recorder, RecorderConfig
from hil.bag.run_info import RunInfo
from hil.core.samples import ImuSample, PoseSample
from tests.bag.bag_streams import (
    FOREIGN_BAGS,
    foreign_bag_paths,
    one_of_each,
    tree_digest,
    write_raw_mcap,
)

needs_foreign = pytest.mark.skipif(
    not FOREIGN_BAGS.is_dir(), reason=f"no foreign bags at {FOREIGN_BAGS}"
)

# Per foreign bag: ("describe", messages, decodable messages) or ("error", class, match).
FOREIGN_EXPECTED: dict[str, tuple[str, object, object]] = {
    "mcap_cdr_test": ("describe", 7, 7),
    "sqlite3_talker": ("describe", 20, 20),
    "empty_sqlite3": ("describe", 0, 0),
    "bare_topics_and_services.mcap": ("describe", 13, 7),
    "protobuf_foxglove_log.mcap": ("describe", 6, 0),
    "truncated_60pct": ("describe", 20, 20),
    "bitflip_middle": ("describe", 75, 74),
    "split_no_metadata": ("error", BagFormatError, "no metadata.yaml"),
}


@needs_foreign
@pytest.mark.parametrize("path", foreign_bag_paths(), ids=lambda p: p.name)
def test_foreign_bag_is_described_or_refused_clearly_and_left_unmodified(path: Path) -> None:
    before = tree_digest(path)
    kind, first, second = FOREIGN_EXPECTED[path.name]
    if kind == "error":
        with pytest.raises(first, match=second):  # type: ignore[call-overload]
            describe(path)
    else:
        with BagReader(path) as reader:
            info = reader.info
            assert info.message_count == first
            assert not info.is_hil_run
            with pytest.raises(NotAHilRunError, match="not a hil run: none of hil's topics"):
                reader.require_hil_run()
            with pytest.raises(NotAHilRunError):
                next(iter(reader.records()))
            decoded = sum(1 for _ in reader.decoded(on_error="skip"))
            assert decoded == second
            assert len(reader.skipped) == first - second
            assert all(str(path) in s.reason for s in reader.skipped)
    assert tree_digest(path) == before


@needs_foreign
def test_bitflip_reports_the_bad_message_with_its_time() -> None:
    with (
        BagReader(FOREIGN_BAGS / "bitflip_middle") as reader,
        pytest.raises(
            MessageDecodeError, match=r"'c_strings' at t=123000000 ns .* does not decode"
        ),
    ):
        for _ in reader.decoded():
            pass


@needs_foreign
def test_truncated_file_is_read_up_to_the_damage_and_says_so() -> None:
    info = describe(FOREIGN_BAGS / "truncated_60pct")
    assert info.problems == ("talker.mcap: file ends early (truncated): stopped at EndOfFile",)
    assert {t.name: t.message_count for t in info.topics}["/topic"] == 10


@needs_foreign
@pytest.mark.parametrize(
    ("name", "topic", "error", "match"),
    [
        (
            "protobuf_foxglove_log.mcap",
            "/text_log",
            UnsupportedBagError,
            "profile '' is not 'ros2'",
        ),
        (
            "bare_topics_and_services.mcap",
            "/add_two_ints/_service_event",
            SchemaError,
            "service schemas are not supported",
        ),
    ],
)
def test_undecodable_topic_raises_a_specific_error(
    name: str, topic: str, error: type[BagError], match: str
) -> None:
    with BagReader(FOREIGN_BAGS / name) as reader:
        assert not {t.name: t for t in reader.info.topics}[topic].decodable
        with pytest.raises(error, match=match):
            next(iter(reader.decoded([topic])))


def test_missing_path(tmp_path: Path) -> None:
    with pytest.raises(BagNotFoundError, match=r"'.*nowhere' does not exist"):
        describe(tmp_path / "nowhere")


def test_file_that_is_not_a_log(tmp_path: Path) -> None:
    path = tmp_path / "notes.mcap"
    path.write_bytes(b"hello world, not a bag")
    with pytest.raises(BagFormatError, match="neither an MCAP nor an sqlite3 file"):
        describe(path)


def test_garbage_metadata(tmp_path: Path) -> None:
    (tmp_path / "metadata.yaml").write_text("rosbag2_bagfile_information: [1, 2")
    with pytest.raises(BagFormatError, match="cannot read rosbag2 metadata"):
        describe(tmp_path)


def test_metadata_listing_a_missing_split(tmp_path: Path) -> None:
    bag = tmp_path / "run"
    with Recorder(bag) as recorder:
        recorder.record(ImuSample(1, 0.0, 0.0, 0.0))
    (bag / "run_0.mcap").unlink()
    with pytest.raises(BagFormatError, match=r"lists 'run_0\.mcap'.* does not exist"):
        describe(bag)


def test_reader_use_before_open(tmp_path: Path) -> None:
    with pytest.raises(ReplayError, match="not open"):
        _ = BagReader(tmp_path).info


def _imu(t_ns: int, rate: float) -> tuple[str, int, bytes]:
    ((topic, payload),) = encode(ImuSample(t_ns, 0.0, 0.0, rate))
    return topic, t_ns, payload


def test_out_of_order_and_duplicate_times_come_out_sorted(tmp_path: Path) -> None:
    path = tmp_path / "shuffled.mcap"
    write_raw_mcap(path, [_imu(30, 3.0), _imu(10, 1.0), _imu(20, 2.0), _imu(20, 2.5)])
    with BagReader(path) as reader:
        got = [(t, r.yaw_rate_radps) for _, t, r in reader.records()]  # type: ignore[union-attr]
    assert got == [(10, 1.0), (20, 2.0), (20, 2.5), (30, 3.0)]


def test_nan_in_a_message_is_reported_or_skipped(tmp_path: Path) -> None:
    path = tmp_path / "nan.mcap"
    _, (topic, good) = encode(PoseSample(10, 1.0, 2.0, 0.0))  # /hil/pose
    # Same layout, x replaced by NaN: the float64 after the 4+8+4+6-byte header and padding.
    bad = bytearray(good)
    offset = len(good) - 43 * 8
    bad[offset : offset + 8] = struct.pack("<d", math.nan)
    write_raw_mcap(path, [(topic, 10, good), (topic, 20, bytes(bad)), (topic, 30, good)])
    before = tree_digest(path)
    with (
        BagReader(path) as reader,
        pytest.raises(
            MessageDecodeError,
            match=r"'/hil/pose' at t=20 ns is not a valid sample",
        ),
    ):
        list(reader.records())
    with BagReader(path) as reader:
        assert [t for _, t, _ in reader.records(on_error="skip")] == [10, 30]
        assert [(s.topic, s.t_ns) for s in reader.skipped] == [(topic, 20)]
    assert tree_digest(path) == before


def test_log_of_another_scenario_is_visible_in_its_run_info(tmp_path: Path) -> None:
    bag = tmp_path / "run"
    with Recorder(bag, RunInfo("other.toml", "sha256:other", 1)) as recorder:
        recorder.record(ImuSample(1, 0.0, 0.0, 0.0))
    run = describe(bag).run
    assert run is not None
    assert (run.scenario_file, run.scenario_hash, run.seed) == ("other.toml", "sha256:other", 1)


def test_split_bag_reads_in_time_order_across_files(tmp_path: Path) -> None:
    bag = tmp_path / "run"
    with Recorder(bag, config=RecorderConfig(split_s=0.01, flush_s=0.01, threaded=False)) as rec:
        for i in range(30):
            rec.record(ImuSample(1000 - i, 0.0, 0.0, float(i)))  # times run backwards
            if i % 10 == 9:
                time.sleep(0.02)
    assert len(rec.files) >= 2
    with BagReader(bag) as reader:
        times = [t for _, t, _ in reader.records()]
        assert reader.info.files == rec.files
    assert times == sorted(times)
    assert len(times) == 30


def test_bag_copied_elsewhere_still_reads(tmp_path: Path) -> None:
    bag = tmp_path / "run"
    with Recorder(bag) as recorder:
        recorder.record(ImuSample(5, 0.0, 0.0, 1.0))
    copy = tmp_path / "copy"
    shutil.copytree(bag, copy)
    assert describe(copy).message_count == 2  # the sample and /tf_static


def test_empty_unfinished_split_is_reported_not_fatal(tmp_path: Path) -> None:
    bag = tmp_path / "run"
    with Recorder(bag) as recorder:
        recorder.record(ImuSample(5, 0.0, 0.0, 1.0))
    (bag / "run_1.mcap").write_bytes(b"")  # killed before its first flush
    info = describe(bag)
    assert info.message_count == 2  # the sample and /tf_static
    assert any(p.startswith("run_1.mcap: file ends early") for p in info.problems)


def _read_everything(path: Path) -> None:
    with BagReader(path) as reader:
        for _ in reader.decoded(on_error="skip"):
            pass


@pytest.mark.parametrize("damage", ["truncate", "flip"])
def test_damaged_copies_give_only_bag_errors(tmp_path: Path, damage: str) -> None:
    """Cut or corrupt a recorded split at many places: a BagError or data, never a crash."""
    bag = tmp_path / "run"
    with Recorder(bag, config=RecorderConfig(chunk_bytes=2048, threaded=False)) as recorder:
        for i in range(60):
            for record in one_of_each(1_000_000 + i * 10_000_000, i):
                recorder.record(record)
            if i % 15 == 14:
                recorder.flush()
    split = bag / "run_0.mcap"
    original = split.read_bytes()
    rng = np.random.default_rng(6)
    outcomes = {"read": 0, "error": 0}
    for position in rng.integers(0, len(original), size=15):
        data = bytearray(original)
        if damage == "truncate":
            data = data[: int(position)]
        else:
            data[int(position) : int(position) + 4] = bytes(
                b ^ 0xA5 for b in data[position : position + 4]
            )
        split.write_bytes(bytes(data))
        try:
            _read_everything(bag)
            outcomes["read"] += 1
        except BagError:
            outcomes["error"] += 1
    assert sum(outcomes.values()) == 15
    assert outcomes["read"] > 0


def test_unknown_type_without_schema_is_described_not_decoded(tmp_path: Path) -> None:
    path = tmp_path / "unknown.mcap"
    with path.open("wb") as stream:
        writer = McapWriter(stream)
        writer.start(profile="ros2", library="test")
        channel = writer.register_channel("/mystery", "cdr", 0, {})
        writer.add_message(channel, 5, b"\x00\x01\x00\x00\x01\x02", 5)
        writer.finish()  # type: ignore[no-untyped-call]
    with BagReader(path) as reader:
        (topic,) = reader.info.topics
        assert (topic.name, topic.decodable) == ("/mystery", False)
        with pytest.raises(SchemaError, match="has no schema in the bag"):
            list(reader.decoded())
        assert list(reader.decoded(on_error="skip")) == []
        assert len(reader.skipped) == 1
