"""Recovery makes a truncated bag whole for every tool; inspecting it changes nothing."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from rosbags.highlevel import AnyReader

from hil.bag.errors import BagNotFoundError, RecoveryError
from hil.bag.reader import BagReader, describe
from hil.bag.recorder import Recorder, RecorderConfig
from hil.bag.recover import inspect_recovery, recover
from hil.core.samples import ImuSample
from tests.bag.bag_streams import FOREIGN_BAGS, tree_digest


def _recorded(tmp_path: Path, n: int = 400) -> Path:
    """A bag of `n` IMU messages in one split of many small chunks."""
    bag = tmp_path / "run"
    config = RecorderConfig(chunk_bytes=1024, threaded=False)
    with Recorder(bag, config=config) as recorder:
        for i in range(n):
            recorder.record(ImuSample(i * 10_000_000, 0.0, 0.0, float(i)))
            if i % 20 == 19:
                recorder.flush()  # one chunk per flush, as the writer does every 0.5 s
    return bag


def _truncate(path: Path, fraction: float) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * fraction)])


def test_truncated_split_reads_complete_chunks_then_recovers(tmp_path: Path) -> None:
    bag = _recorded(tmp_path)
    _truncate(bag / "run_0.mcap", 0.6)
    before = tree_digest(bag)
    info = describe(bag)
    assert "file ends early" in info.problems[0]
    kept = info.message_count
    assert 100 < kept < 400
    with BagReader(bag) as reader:
        rates = [r.yaw_rate_radps for _, _, r in reader.records()]  # type: ignore[union-attr]
    assert rates == [float(i) for i in range(kept - 1)]  # a prefix (and /tf_static), unharmed

    plan = inspect_recovery(bag)
    assert plan.rewritten == ("run_0.mcap",)
    assert tree_digest(bag) == before  # inspecting and reading never write

    report = recover(bag)
    assert report.messages == kept
    assert describe(bag).problems == ()
    with AnyReader([bag]) as reader:
        assert sum(1 for _ in reader.messages()) == kept
    assert not inspect_recovery(bag).changed


def test_unfinished_split_is_listed_after_recovery(tmp_path: Path) -> None:
    bag = _recorded(tmp_path, 50)
    # A killed recorder leaves its current split in the directory, not in metadata.yaml.
    shutil.copy(bag / "run_0.mcap", bag / "run_1.mcap")
    _truncate(bag / "run_1.mcap", 0.9)
    info = describe(bag)
    assert any("not listed" in p for p in info.problems)
    with AnyReader([bag]) as reader:
        # other tools see the listed split only: 50 samples and /tf_static
        assert sum(1 for _ in reader.messages()) == 51
    recover(bag)
    with AnyReader([bag]) as reader:
        total = sum(1 for _ in reader.messages())
    assert total == describe(bag).message_count
    assert total > 50


def test_healthy_bag_is_left_byte_for_byte(tmp_path: Path) -> None:
    bag = _recorded(tmp_path, 20)
    before = tree_digest(bag)
    report = recover(bag)
    assert not report.changed
    assert tree_digest(bag) == before


def test_truncated_split_without_a_complete_chunk_is_removed(tmp_path: Path) -> None:
    bag = _recorded(tmp_path, 20)
    (bag / "run_1.mcap").write_bytes((bag / "run_0.mcap").read_bytes()[:40])
    report = recover(bag)
    assert report.removed == ("run_1.mcap",)
    assert not (bag / "run_1.mcap").exists()
    assert describe(bag).message_count == 21  # 20 samples and /tf_static


@pytest.mark.skipif(not FOREIGN_BAGS.is_dir(), reason="no foreign bags")
def test_foreign_truncated_bag_recovers_in_a_copy(tmp_path: Path) -> None:
    source = FOREIGN_BAGS / "truncated_60pct"
    before = tree_digest(source)
    copy = tmp_path / "talker"
    shutil.copytree(source, copy)
    for path in copy.iterdir():
        path.chmod(0o644)
    recover(copy)
    with AnyReader([copy]) as reader:
        assert sum(1 for _ in reader.messages()) == 20
    assert tree_digest(source) == before


def test_errors(tmp_path: Path) -> None:
    with pytest.raises(BagNotFoundError):
        recover(tmp_path / "nowhere")
    (tmp_path / "empty").mkdir()
    with pytest.raises(RecoveryError, match=r"no metadata\.yaml"):
        recover(tmp_path / "empty")
