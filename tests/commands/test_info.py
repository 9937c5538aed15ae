"""`hil info` prints a summary, or one clear line and exit status 2."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from hil.bag.recorder import Recorder
from hil.bag.run_info import RunInfo
from hil.commands import info
from hil.core.samples import ImuSample
from tests.bag.bag_streams import tree_digest

FOREIGN_BAGS = Path(__file__).resolve().parents[2].parent / "shared" / "foreign_bags"


def run_info(*argv: str) -> int:
    parser = argparse.ArgumentParser()
    info.add_arguments(parser)
    return info.run(parser.parse_args(list(argv)))


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    path = tmp_path / "run"
    with Recorder(path, RunInfo("paper.toml", "sha256:abc", 4, "0.1.0", "0123456789abcdef")) as rec:
        for i in range(5):
            rec.record(ImuSample(1_000_000_000 + i * 10_000_000, 0.0, 0.0, 0.1))
    return path


def test_text_summary(bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run_info(str(bag)) == 0
    out = capsys.readouterr().out
    assert "messages:  6" in out  # 5 samples and /tf_static
    assert "/voyager/measurement/imu" in out
    assert "scenario paper.toml (hash sha256:abc), seed 4" in out
    assert "start 1.000000000 s, end 1.040000000 s" in out
    assert "not a hil run" not in out


def test_json_summary(bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run_info(str(bag), "--json") == 0
    data = json.loads(capsys.readouterr().out)
    assert data["message_count"] == 6  # 5 samples and /tf_static
    assert data["hil_run"] is True
    assert data["custom"]["seed"] == "4"
    types = {t["name"]: t["type"] for t in data["topics"]}
    assert types == {"/voyager/measurement/imu": "sensor_msgs/msg/Imu",
                     "/tf_static": "tf2_msgs/msg/TFMessage"}  # fmt: skip


def test_missing_log_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run_info(str(tmp_path / "nothing")) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1
    assert captured.err.startswith("hil info: error: ")
    assert "does not exist" in captured.err


@pytest.mark.skipif(not FOREIGN_BAGS.is_dir(), reason="no foreign bags")
@pytest.mark.parametrize(
    ("name", "status", "needle"),
    [
        ("mcap_cdr_test", 0, "not a hil run: none of hil's topics"),
        ("protobuf_foxglove_log.mcap", 0, "not decodable: MCAP profile ''"),
        ("split_no_metadata", 2, "no metadata.yaml"),
        ("truncated_60pct", 0, "file ends early"),
    ],
)
def test_foreign_logs(
    name: str, status: int, needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    path = FOREIGN_BAGS / name
    before = tree_digest(path)
    assert run_info(str(path)) == status
    captured = capsys.readouterr()
    assert needle in captured.out + captured.err
    assert "Traceback" not in captured.err
    assert tree_digest(path) == before


@pytest.mark.skipif(not FOREIGN_BAGS.is_dir(), reason="no foreign bags")
def test_check_reports_the_bitflipped_message(capsys: pytest.CaptureFixture[str]) -> None:
    assert run_info(str(FOREIGN_BAGS / "bitflip_middle"), "--check") == 1
    out = capsys.readouterr().out
    assert "check:     1 message(s) do not decode" in out
    assert "t=123000000 ns" in out
