"""`hil record-suite`: the suite's runs, deterministic bags, and what changed."""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
from pathlib import Path

import pytest

from hil.commands import record_suite
from hil.commands.record_suite import SuiteRun, describe_change, record_run, suite
from hil.runtime.settings import LoopConfig

LOGS = Path(__file__).resolve().parents[2] / "logs"


def run_cmd(*argv: str) -> int:
    parser = argparse.ArgumentParser()
    record_suite.add_arguments(parser)
    return record_suite.run(parser.parse_args(list(argv)))


def test_suite_covers_starts_a_moving_obstacle_and_faults() -> None:
    runs = suite()
    assert len({r.spec.start for r in runs}) >= 3
    assert any(r.spec.motions for r in runs)
    assert any(r.spec.pose_outages_s and r.spec.thruster_outages for r in runs)
    assert len({r.name for r in runs}) == len(runs)
    assert {r.name for r in runs} <= {p.name for p in LOGS.iterdir()}


def test_list_and_bad_arguments(capsys: pytest.CaptureFixture[str]) -> None:
    assert run_cmd("--list") == 0
    assert "coarse-faults-seed4: pose lost" in capsys.readouterr().out
    assert run_cmd("--only", "nope") == 2
    assert "unknown run(s) ['nope']" in capsys.readouterr().err


def test_a_run_records_the_same_bytes_twice(tmp_path: Path) -> None:
    (base,) = [r for r in suite() if r.name == "coarse-faults-seed4"]
    # 25 s of the run (it stops at the time limit): the pose outage at 20 s included.
    spec = dataclasses.replace(base.spec, loop=LoopConfig(max_duration_s=25.0))
    short = SuiteRun(base.name, spec, base.note)
    first = record_run(short, tmp_path / "a")
    second = record_run(short, tmp_path / "b")
    digests = [
        {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(d.glob("*.mcap"))}
        for d in (first, second)
    ]
    assert digests[0] == digests[1]
    assert describe_change(first, second).startswith("unchanged decisions")
    changed = describe_change(LOGS / "coarse-high-seed2", LOGS / "coarse-low-seed1")
    assert changed.startswith("decisions changed (first at t=")
    assert "old log unreadable" in describe_change(tmp_path / "missing", first)
