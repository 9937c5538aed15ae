"""`hil recover` makes a killed recording whole; --dry-run writes nothing."""

from __future__ import annotations

import argparse
import hashlib
import json
from pathlib import Path

import pytest
from rosbags.highlevel import AnyReader

from hil.bag.recorder import Recorder, RecorderConfig
from hil.commands import recover as command
from hil.core.samples import ImuSample


def run_recover(*argv: str) -> int:
    parser = argparse.ArgumentParser()
    command.add_arguments(parser)
    return command.run(parser.parse_args(list(argv)))


def digest(path: Path) -> dict[str, str]:
    return {str(p): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(path.rglob("*"))}


@pytest.fixture
def killed_bag(tmp_path: Path) -> Path:
    bag = tmp_path / "run"
    with Recorder(bag, config=RecorderConfig(chunk_bytes=1024, threaded=False)) as recorder:
        for i in range(100):
            recorder.record(ImuSample(i, 0.0, 0.0, float(i)))
            if i % 10 == 9:
                recorder.flush()
    data = (bag / "run_0.mcap").read_bytes()
    (bag / "run_0.mcap").write_bytes(data[: len(data) // 2])
    return bag


def test_dry_run_then_recover(killed_bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = digest(killed_bag)
    assert run_recover(str(killed_bag), "--dry-run") == 0
    assert "would rewrite run_0.mcap" in capsys.readouterr().out
    assert digest(killed_bag) == before
    assert run_recover(str(killed_bag), "--json") == 0
    report = json.loads(capsys.readouterr().out)
    assert report["rewritten"] == ["run_0.mcap"]
    with AnyReader([killed_bag]) as reader:
        assert sum(1 for _ in reader.messages()) == report["messages"] > 0
    assert run_recover(str(killed_bag)) == 0
    assert "nothing to recover" in capsys.readouterr().out


def test_missing_log(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run_recover(str(tmp_path / "none")) == 2
    assert capsys.readouterr().err.startswith("hil recover: error: ")
