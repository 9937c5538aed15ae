"""Replay of recorded runs: the committed suite passes, tampered and bad logs are caught."""

from __future__ import annotations

import dataclasses
import importlib.metadata
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from hil.bag.reader import BagReader
from hil.bag.run_data import load_run
from hil.core.records import Decision, StateEstimate
from hil.replay.controllers import ScenarioCache
from hil.replay.options import Tolerance
from hil.replay.regression import Status
from tests.bag.bag_streams import foreign_bag_paths
from tests.replay.suite_logs import LOGS, REFERENCE, SUITE_LOGS, replay_unmodified, rewrite


def test_suite_is_present() -> None:
    assert len(SUITE_LOGS) >= 4, f"regenerate with `hil record-suite`: {LOGS}"


@pytest.mark.parametrize("log", SUITE_LOGS, ids=[p.name for p in SUITE_LOGS])
def test_every_suite_log_replays_without_regression(log: Path, caches: ScenarioCache) -> None:
    report = replay_unmodified(log, caches)
    assert report.error == ""
    assert report.status in (Status.PASS, Status.WARN), report.regressions
    assert report.check("decisions").status is Status.PASS
    over_ros = "-ros-" in log.name  # recorded over DDS: the stack re-run is not judged there
    assert report.check("stack").status is (Status.SKIP if over_ros else Status.PASS)
    # The paper's tank figures are figures, no threshold: the tracking check passes.
    assert report.check("tracking").status is Status.PASS
    assert report.check("tracking").metrics["paper_rms"] == [0.00768, 0.00431, 0.62108]
    assert report.check("decisions").metrics["decisions"] > 10


def test_changed_chosen_input_is_a_regression_at_its_time(
    tmp_path: Path, caches: ScenarioCache
) -> None:
    with BagReader(REFERENCE) as reader:
        records = [r for _, _, r in reader.records()]
    index, decision = next(
        (i, r)
        for i, r in enumerate(records)
        if isinstance(r, Decision) and len(r.safe_input_indices) >= 2 and r.t_ns > 10**10
    )
    other = next(
        k for k, idx in enumerate(decision.safe_input_indices) if idx != decision.chosen_index
    )
    tampered = dataclasses.replace(
        decision,
        chosen_index=decision.safe_input_indices[other],
        chosen_input=decision.safe_inputs[other],
    )
    copy = rewrite(REFERENCE, tmp_path / "tampered", {index: tampered})
    report = replay_unmodified(copy, caches)
    assert report.status is Status.FAIL
    check = report.check("decisions")
    assert check.status is Status.FAIL
    first = check.findings[0]
    assert first.t_ns == decision.t_ns
    assert first.data["fields"] == ["chosen_index"]  # consistent, but not what J picks
    assert first.data["recorded"]["chosen"] == tampered.chosen_index
    assert first.data["replayed"]["chosen"] == decision.chosen_index
    assert first.data["replayed"]["safe"] == sorted(decision.safe_input_indices)
    stack = report.check("stack")  # the re-run chose otherwise: no tie, no boundary
    assert stack.status is Status.FAIL
    assert stack.metrics["divergence"] is None
    assert stack.findings[0].t_ns == decision.t_ns


def test_raised_tracking_error_is_a_regression_at_its_time(
    tmp_path: Path, caches: ScenarioCache
) -> None:
    with BagReader(REFERENCE) as reader:
        records = [r for _, _, r in reader.records()]
    index, estimate = next(
        (i, r)
        for i, r in enumerate(records)
        if isinstance(r, StateEstimate) and r.t_ns >= 20 * 10**9
    )
    raised = dataclasses.replace(estimate, surge_mps=estimate.surge_mps + 0.5)
    copy = rewrite(REFERENCE, tmp_path / "tracking", {index: raised})
    report = replay_unmodified(copy, caches, tolerance=Tolerance.parse("surge_max=0.4"))
    stack = report.check("stack")
    assert stack.status is Status.FAIL
    assert stack.findings[0].t_ns == estimate.t_ns
    assert any(
        "surge tracking max" in f.message and f.t_ns == estimate.t_ns for f in stack.findings
    )
    tracking = report.check("tracking")  # a threshold on the largest error catches it too
    assert tracking.status is Status.FAIL
    assert tracking.metrics["t_max_ns"][0] == estimate.t_ns
    (finding,) = [f for f in tracking.findings if "max threshold" in f.message]
    assert finding.t_ns == estimate.t_ns
    assert (
        replay_unmodified(
            REFERENCE, caches, tolerance=Tolerance.parse("surge_max=0.4"), stack=False
        )
        .check("tracking")
        .status
        is Status.PASS
    )


def test_missing_log_is_an_error(tmp_path: Path, caches: ScenarioCache) -> None:
    report = replay_unmodified(tmp_path / "nope", caches)
    assert report.status is Status.ERROR
    assert "does not exist" in report.error


def test_truncated_log_replays_what_survived_with_a_warning(
    tmp_path: Path, caches: ScenarioCache
) -> None:
    copy = tmp_path / REFERENCE.name
    shutil.copytree(REFERENCE, copy)
    (split,) = copy.glob("*.mcap")
    data = split.read_bytes()
    split.write_bytes(data[: int(len(data) * 0.6)])
    report = replay_unmodified(copy, caches)
    assert any("bag:" in w for w in report.warnings), report.warnings
    assert report.error == ""
    assert report.status in (Status.PASS, Status.WARN), report.regressions
    full = load_run(REFERENCE)
    assert 0 < len(load_run(copy).pose) < len(full.pose)


@pytest.mark.parametrize("path", foreign_bag_paths(), ids=lambda p: p.name)
def test_foreign_logs_give_a_clear_error_and_stay_unmodified(
    path: Path, caches: ScenarioCache
) -> None:
    report = replay_unmodified(path, caches)
    assert report.status is Status.ERROR
    assert report.error
    assert "\n" not in report.error
    assert "internal error" not in report.error


def test_pytest_plugin_turns_each_log_into_a_test(tmp_path: Path) -> None:
    logs = tmp_path / "logs"
    shutil.copytree(REFERENCE, logs / REFERENCE.name)
    (logs / "broken").mkdir()
    (logs / "broken" / "broken_0.mcap").write_bytes(b"not an mcap file")
    (logs / "notes").mkdir()  # not a bag: ignored
    (tmp_path / "empty").mkdir()
    # Once the pytest11 entry point is installed the plugin loads by itself.
    installed = any(
        e.value == "hil.replay.pytest_plugin"
        for e in importlib.metadata.entry_points(group="pytest11")
    )
    load = [] if installed else ["-p", "hil.replay.pytest_plugin"]
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            *load,
            "--hil-logs",
            str(logs),
            "-p",
            "no:cacheprovider",
            "-q",
            "-W",
            "error",
            "-c",
            os.devnull,
            "--rootdir",
            str(tmp_path),
            str(tmp_path / "empty"),
        ],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
        check=False,
    )
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "1 failed, 1 passed" in proc.stdout
    assert "broken: ERROR" in proc.stdout
    assert "not a rosbag2 bag" in proc.stdout
    assert "Traceback" not in proc.stdout
