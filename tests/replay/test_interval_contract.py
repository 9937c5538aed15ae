"""Replay holds every interval to its decision's contract; old logs are refused.

A short run recorded on the packaged coarse scenario (a winning set under its measured
transient budget) keeps its contracts; the same log with the estimates of one interval
pushed out of the tube, or with a velocity beyond the envelope, FAILs naming the interval
and the size.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hil.bag.reader import BagReader
from hil.bag.run_data import RunData, load_run
from hil.core.records import StateEstimate
from hil.replay.context import ReplayContext
from hil.replay.controllers import ScenarioCache, resolve_scenario
from hil.replay.intervals import VELOCITY_ESTIMATE_TOLERANCE, check_contract, judge_intervals
from hil.replay.options import ReplayOptions
from hil.replay.regression import Check, Finding, Interval, Status, exit_code
from hil.replay.replayer import replay_log
from hil.runs.sim_run import SimRunSpec, simulate
from hil.runtime.settings import NS_PER_S, LoopConfig
from hil.scenarios import load_scenario
from tests.replay.suite_logs import rewrite


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("contract")
    out = folder / "run"
    simulate(SimRunSpec(scenario="coarse", seed=1, out_dir=out, cache_dir=folder / "t",
                        loop=LoopConfig(resynthesis_period_s=None, max_duration_s=12.0)))
    return out


@pytest.fixture(scope="module")
def cache() -> ScenarioCache:
    return ScenarioCache()


def _judge(run: RunData, cache: ScenarioCache) -> tuple[tuple[Interval, ...], Check]:
    """Judge `run` against its scenario's measured transient budget."""
    scenario = resolve_scenario(run)
    check = check_contract(ReplayContext(run, scenario, cache))
    return check.intervals, check


def _edit_estimates(src: Path, dst: Path, start_ns: int, stop_ns: int,
                    dx: float = 0.0, du: float = 0.0) -> Path:
    """Rewrite `src` with the estimates in [start, stop) moved by dx (m) and du (surge m/s)."""
    with BagReader(src) as reader:
        records = [r for _, _, r in reader.records()]
    edit = {
        n: replace(r, x_m=r.x_m + dx, surge_mps=r.surge_mps + du)
        for n, r in enumerate(records)
        if isinstance(r, StateEstimate) and start_ns <= r.t_ns < stop_ns
    }
    assert edit
    return rewrite(src, dst, edit)  # type: ignore[arg-type]


def test_a_clean_run_keeps_its_contracts(recorded: Path, cache: ScenarioCache) -> None:
    intervals, contract = _judge(load_run(recorded), cache)
    assert contract.status is Status.PASS, contract.findings
    assert contract.metrics["intervals_judged"] >= 5
    judged = [i for i in intervals if i.tube_contained is not None]
    assert all(i.status is Status.PASS for i in judged)
    assert all(i.tube_distance_m is not None for i in judged)
    assert sum(i.successor_contained is True and i.value_decreased is True for i in judged) >= 4


def test_estimates_leaving_the_tube_fail_the_interval(
    recorded: Path, cache: ScenarioCache, tmp_path: Path
) -> None:
    d = load_run(recorded).decisions[3]
    edited = _edit_estimates(recorded, tmp_path / "pushed", d.t_ns + NS_PER_S // 2,
                             d.t_ns + NS_PER_S, dx=0.5)
    intervals, contract = _judge(load_run(edited), cache)
    assert contract.status is Status.FAIL
    assert len(contract.findings) == 1
    finding = contract.findings[0]
    assert finding.t_ns == d.t_ns
    assert f"interval t={d.t_ns / NS_PER_S:.3f} s" in finding.message
    match = re.search(r"estimate (\d+\.\d+) m from the tube cells", finding.message)
    assert match is not None
    size = float(match.group(1))
    assert 0.2 < size <= 0.5
    assert finding.data["tube_distance_m"] == pytest.approx(size, abs=1e-4)
    interval = next(i for i in intervals if i.t_ns == d.t_ns)
    assert interval.status is Status.FAIL
    assert interval.tube_contained is False
    assert [i.t_ns for i in intervals if i.status is Status.FAIL] == [d.t_ns]
    # End to end: the replay fails (exit 1) and its report names the interval.
    report = replay_log(edited, ReplayOptions(intervals=True), cache)
    assert exit_code([report]) == 1
    assert any(f.t_ns == d.t_ns and "from the tube cells" in f.message
               for f in report.check("contract").findings)
    assert next(i for i in report.intervals if i.t_ns == d.t_ns).tube_contained is False


def test_a_velocity_beyond_the_envelope_fails(
    recorded: Path, cache: ScenarioCache, tmp_path: Path
) -> None:
    d = load_run(recorded).decisions[4]
    edited = _edit_estimates(recorded, tmp_path / "fast", d.t_ns + NS_PER_S,
                             d.t_ns + NS_PER_S + NS_PER_S // 10, du=0.3)
    intervals, contract = _judge(load_run(edited), cache)
    assert contract.status is Status.FAIL
    assert len(contract.findings) == 1
    finding = contract.findings[0]
    assert finding.t_ns == d.t_ns
    assert "velocity error beyond the envelope + estimate tolerance on surge by" in (
        finding.message
    )
    interval = next(i for i in intervals if i.t_ns == d.t_ns)
    assert interval.envelope_exceeded == ("surge",)
    assert interval.envelope_excess is not None
    # 0.3 m/s on an error within envelope + tolerance: the excess is below 0.3, and above
    # 0.3 less the largest bound.
    bound = load_scenario("coarse").transient.envelopes[:, :, 0].max()
    assert 0.3 - bound - VELOCITY_ESTIMATE_TOLERANCE[0] < interval.envelope_excess[0] < 0.3


def test_the_envelope_is_the_decisions_class_at_that_time(
    recorded: Path, cache: ScenarioCache
) -> None:
    run = load_run(recorded)
    scenario = resolve_scenario(run)
    controllers = cache.get(scenario)
    # A budget with zero envelopes: every error beyond the estimate's tolerance fails.
    zero = replace(scenario, transient=replace(
        scenario.transient, envelopes=np.zeros_like(scenario.transient.envelopes)))
    strict = judge_intervals(run, controllers, zero, [])
    loose, _ = _judge(run, cache)
    assert not any(i.envelope_exceeded for i in loose)
    assert any(i.envelope_exceeded for i in strict)


def test_a_log_of_format_1_is_refused(recorded: Path, tmp_path: Path,
                                      cache: ScenarioCache) -> None:
    old = tmp_path / "old"
    rewrite(recorded, old, {})
    meta = old / "metadata.yaml"
    meta.write_text(re.sub(r'"hil_format": "\d+"', '"hil_format": "1"', meta.read_text()))
    report = replay_log(old, ReplayOptions(), cache)
    assert report.status is Status.ERROR
    assert exit_code([report]) == 2
    assert "\n" not in report.error
    assert "format 1" in report.error
    assert "recorded before the reference-aware symbolic controller" in report.error
    assert "must be re-recorded" in report.error


def test_a_failed_check_marks_the_interval_it_names(
    recorded: Path, cache: ScenarioCache
) -> None:
    run = load_run(recorded)
    scenario = resolve_scenario(run)
    t = run.decisions[2].t_ns + 1
    failed = Check("stack", Status.FAIL, "x", (Finding("differs", t),))
    intervals = judge_intervals(run, cache.get(scenario), scenario, [failed])
    assert intervals[2].status is Status.FAIL
    assert intervals[2].notes[0] == "a failed check names a time in this interval"
    assert intervals[1].t_ns < t < intervals[3].t_ns


def test_a_run_ended_by_its_time_limit_is_re_run_to_its_end(
    recorded: Path, cache: ScenarioCache
) -> None:
    """The fixture's run timed out at 12 s and braked: the time limit is the run's setting,
    not the stack's, so the re-run stops where the recording did and brakes the same way."""
    run = load_run(recorded)
    timeout = [e for e in run.events if e.code == "timeout"]
    assert len(timeout) == 1
    report = replay_log(recorded, ReplayOptions(), cache)
    stack = next(c for c in report.checks if c.name == "stack")
    assert stack.status is Status.PASS, stack.findings
    assert stack.metrics["end_reason"] == timeout[0].text
    assert run.reference.t_ns[-1] > timeout[0].t_ns  # braking was compared too
