"""Replay of recorded runs: the committed suite passes, tampered and bad logs are caught."""

from __future__ import annotations

import dataclasses
import importlib.metadata
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hil.adapters.log import RecordedRun, Stream, read_log
from hil.bag.messages import Record
from hil.bag.reader import BagInfo, BagReader
from hil.bag.recorder import RecorderConfig, RunInfo
from hil.commands.record_suite import write_bag
from hil.core.records import Decision, StateEstimate
from hil.replay.regression import LogReport, Status
from hil.replay.replayer import (
    ReplayOptions,
    ScenarioCache,
    Tolerance,
    check_margin,
    recompute,
    replay_log,
    resolve_scenario,
)
from hil.runs.sim_run import spec_from_json, spec_to_json
from hil.runtime.assembly import layout_from_scenario
from hil.scenarios import TrackingMargin, load_scenario
from tests.bag.bag_streams import foreign_bag_paths, tree_digest

LOGS = Path(__file__).resolve().parents[2] / "logs"
SUITE_LOGS = sorted(p for p in LOGS.iterdir() if (p / "metadata.yaml").is_file())
REFERENCE = LOGS / "coarse-high-seed2"  # the shortest run of the suite
CONFIG = RecorderConfig(split_s=1e9, flush_s=1e9, threaded=False)


@pytest.fixture(scope="module")
def caches() -> ScenarioCache:
    """Controllers shared by every replay of this module (one synthesis per layout)."""
    return ScenarioCache()


def _replay(path: Path, caches: ScenarioCache, **options: object) -> LogReport:
    before = tree_digest(path) if path.exists() else {}
    report = replay_log(path, ReplayOptions(**options), caches)  # type: ignore[arg-type]
    after = tree_digest(path) if path.exists() else {}
    assert after == before, "replay modified its input"
    return report


def _rewrite(src: Path, dst: Path, edit: dict[int, Record]) -> Path:
    """Copy a log record by record through the real recorder, replacing records by index."""
    with BagReader(src) as reader:
        info = RunInfo.from_custom_data(reader.info.custom)
        records = [r for _, _, r in reader.records()]
    assert info is not None
    for i, record in edit.items():
        records[i] = record
    write_bag(dst, info, records, CONFIG)
    return dst


def test_suite_is_present() -> None:
    assert len(SUITE_LOGS) >= 4, f"regenerate with `hil record-suite`: {LOGS}"


@pytest.mark.parametrize("log", SUITE_LOGS, ids=[p.name for p in SUITE_LOGS])
def test_every_suite_log_replays_without_regression(log: Path, caches: ScenarioCache) -> None:
    report = _replay(log, caches)
    assert report.error == ""
    assert report.status in (Status.PASS, Status.WARN), report.regressions
    assert report.check("decisions").status is Status.PASS
    over_ros = "-ros-" in log.name  # recorded over DDS: the stack re-run is advisory there
    assert report.check("stack").status is (Status.WARN if over_ros else Status.PASS)
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
    copy = _rewrite(REFERENCE, tmp_path / "tampered", {index: tampered})
    report = _replay(copy, caches)
    assert report.status is Status.FAIL
    check = report.check("decisions")
    assert check.status is Status.FAIL
    first = check.findings[0]
    assert first.t_ns == decision.t_ns
    assert "chosen input" in first.data["fields"]
    assert first.data["recorded"]["chosen"] == tampered.chosen_index
    assert first.data["replayed"]["chosen"] == decision.chosen_index
    assert first.data["replayed"]["safe"] == sorted(decision.safe_input_indices)
    assert report.check("stack").findings[0].t_ns == decision.t_ns


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
    copy = _rewrite(REFERENCE, tmp_path / "tracking", {index: raised})
    report = _replay(copy, caches, tolerance=Tolerance.parse("surge_max=0.4"))
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
        _replay(REFERENCE, caches, tolerance=Tolerance.parse("surge_max=0.4"), stack=False)
        .check("tracking")
        .status
        is Status.WARN
    )


def test_missing_log_is_an_error(tmp_path: Path, caches: ScenarioCache) -> None:
    report = _replay(tmp_path / "nope", caches)
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
    report = _replay(copy, caches)
    assert any("bag:" in w for w in report.warnings), report.warnings
    assert report.error == ""
    assert report.status in (Status.PASS, Status.WARN), report.regressions
    full = read_log(REFERENCE)
    assert 0 < len(read_log(copy).poses) < len(full.poses)


@pytest.mark.parametrize("path", foreign_bag_paths(), ids=lambda p: p.name)
def test_foreign_logs_give_a_clear_error_and_stay_unmodified(
    path: Path, caches: ScenarioCache
) -> None:
    report = _replay(path, caches)
    assert report.status is Status.ERROR
    assert report.error
    assert "\n" not in report.error
    assert "internal error" not in report.error


def test_log_from_another_scenario_is_refused(tmp_path: Path, caches: ScenarioCache) -> None:
    report = _replay(REFERENCE, caches, scenario="paper")
    assert report.status is Status.ERROR
    assert "another scenario" in report.error
    copy = tmp_path / "renamed"
    shutil.copytree(REFERENCE, copy)
    meta = copy / "metadata.yaml"
    text = meta.read_text().replace('"scenario_file": "coarse"', '"scenario_file": "harbour"')
    meta.write_text(text)
    report = _replay(copy, caches)
    assert report.status is Status.ERROR
    assert "'harbour'" in report.error
    assert "cannot be loaded" in report.error


def test_recompute_mirrors_the_runtime_decision(caches: ScenarioCache) -> None:
    scenario = load_scenario("coarse")
    controller = caches.get(scenario)(layout_from_scenario(scenario))
    start = np.array([3.75, -1.5, np.pi / 2])
    got = recompute(controller, start, np.zeros(3))
    assert got.winning
    assert got.value > 0
    assert got.chosen in got.safe
    assert len(got.safe) >= 1
    in_target = recompute(controller, np.array([-2.75, 1.5, 0.0]), np.zeros(3))
    assert (in_target.value, in_target.safe, in_target.chosen) == (0.0, (), -1)
    outside = recompute(controller, np.array([2.0, -1.5, 0.0]), np.zeros(3))  # inside O1
    assert not outside.winning
    assert outside.chosen == -1


def test_resolve_scenario_checks_the_hash() -> None:
    run = read_log(REFERENCE)
    assert resolve_scenario(run).name == "coarse"


def test_tolerance_parsing() -> None:
    tol = Tolerance.parse("surge=0.05, yaw=4,rel=0.1")
    assert tol.rms[0] == 0.05
    assert tol.rms[2] == 4.0
    assert tol.enforce_rms
    assert tol.relative == 0.1
    assert not Tolerance.parse("").enforce_rms
    assert Tolerance.parse("sway_max=0.3").max_abs == (np.inf, 0.3, np.inf)
    with pytest.raises(ValueError, match="unknown tolerance key 'heave'"):
        Tolerance.parse("heave=1")
    with pytest.raises(ValueError, match="'surge=-1'"):
        Tolerance.parse("surge=-1")
    with pytest.raises(ValueError, match="'yaw'"):
        Tolerance.parse("yaw")


def test_spec_round_trips_through_the_manifest_form() -> None:
    from hil.commands.record_suite import suite

    for item in suite():
        assert spec_from_json(spec_to_json(item.spec)) == item.spec
    with pytest.raises(ValueError, match="malformed run specification"):
        spec_from_json({"seed": 1})


def test_resim_with_the_suite_spec_reproduces_the_recording(
    caches: ScenarioCache,
) -> None:
    resim = _replay(REFERENCE, caches, resim=True, stack=False).check("resim")
    assert resim.metrics["start_from"] == "suite.json entry"
    assert resim.status is Status.PASS, resim.findings
    # Not bit-exact across machines: numba compiles for the host CPU (FMA contraction,
    # vector width), measured at 1.5e-10 m between two x86_64 CPUs over a whole run.
    # 1 um is four orders of magnitude above that noise and below any cell (cm).
    assert resim.metrics["max_deviation_m"] < 1e-6


def test_resim_from_the_first_pose_docks_and_drift_only_warns(
    tmp_path: Path, caches: ScenarioCache
) -> None:
    copy = tmp_path / REFERENCE.name  # no suite.json beside it: start from the first pose
    shutil.copytree(REFERENCE, copy)
    resim = _replay(copy, caches, resim=True, stack=False).check("resim")
    assert resim.metrics["start_from"].startswith("first recorded pose")
    assert resim.status in (Status.PASS, Status.WARN), resim.findings
    assert resim.metrics["docked"]
    assert resim.metrics["max_deviation_m"] < 0.5


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


def _synthetic_run(errors: dict[int, float]) -> RecordedRun:
    """Estimates and references at 20 Hz for 4 s, decisions at 0 s and 2 s; surge errors."""
    t = np.arange(80, dtype=np.int64) * 50_000_000
    est = np.zeros((80, 6))
    for k, e in errors.items():
        est[k, 3] = e
    decisions = tuple(
        Decision.from_arrays(int(td), [0, 0, 0], 0, 5.0, True, [], [], -1, 1, "h")
        for td in (0, 2_000_000_000)
    )
    return RecordedRun(
        Path("synthetic"),
        BagInfo(Path("synthetic"), "mcap", (), (), None, None),
        Stream.empty(3),
        Stream.empty(3),
        Stream(t, est),
        Stream(t, np.zeros((80, 3))),
        Stream.empty(5),
        decisions,
        (),
        (),
        (),
    )


def test_margin_check_says_where_the_error_left_the_margin_after_settling() -> None:
    scenario = load_scenario("coarse").with_margin(TrackingMargin(0.01, 0.02, 0.03))
    # 0.05 m/s at 0.5 s: inside the settling second, not checked; at 3.5 s: outside.
    check = check_margin(_synthetic_run({10: 0.05, 70: 0.05}), scenario, settle_s=1.0)
    assert check.status is Status.WARN
    (finding,) = check.findings
    assert finding.t_ns == 3_500_000_000
    assert finding.data["axis"] == "surge"
    assert check_margin(_synthetic_run({10: 0.05}), scenario).status is Status.PASS
    assert check_margin(_synthetic_run({10: 0.05}), scenario, settle_s=0.0).status is Status.WARN
