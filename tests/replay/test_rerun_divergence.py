"""Re-runs that take a decision the other way: accepted at a boundary or a tie, else a regression.

A run is recorded for real from a start that puts its first decision 1e-11 m short of a
cell boundary, one where the chosen input changes across it. Its pose feed is then
nudged along x before the stack re-run (or its start before the re-simulation), as
another machine's rounding would: by 5e-11 m the re-run lands 4e-11 m beyond the
boundary, within BOUNDARY_TOLERANCE (1e-9), and must pass with the divergence reported;
by 1e-7 m (still within the estimates' 1e-6, so only the decision tells) it lands 1e-7 m
beyond, a change no rounding makes, and must fail.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.bag.messages import Record
from hil.bag.reader import BagReader
from hil.bag.run_data import load_run
from hil.commands.record_suite import SuiteRun, record_run
from hil.controllers.symbolic import SymbolicAdapter
from hil.core.records import Decision
from hil.core.samples import PoseSample
from hil.replay.controllers import ScenarioCache
from hil.replay.decisions import (
    BOUNDARY_TOLERANCE,
    decision_controllers,
    is_cost_tie,
    recompute,
)
from hil.replay.divergence import BOUNDARY, TIE, explain_divergence
from hil.replay.regression import Status, summary_json
from hil.replay.resim import MANIFEST, recorded_spec
from hil.runs.sim_run import SimRunSpec, spec_to_json
from hil.scenarios import load_scenario
from tests.replay.suite_logs import LOGS, REFERENCE, replay_unmodified, rewrite

GAP_M = 1e-11
"""How far short of the boundary the recorded first decision's state lies (m)."""
NOISE_M = 5e-11
"""A nudge of the order of the measured cross-machine noise (1.5e-10 m over a whole run)."""
CHANGE_M = 1e-7
"""A nudge a hundred times the boundary tolerance, ten times below the estimates' 1e-6."""


@dataclass(frozen=True)
class BoundaryLog:
    """A recorded run whose first decision lies just short of a cell boundary.

    Attributes:
        path: The bag.
        spec: The recorded run's specification.
        boundary_x: The boundary's x (m), the first state in the next cell.
        first: The recorded first decision.
    """

    path: Path
    spec: SimRunSpec
    boundary_x: float
    first: Decision


@pytest.fixture(scope="module")
def boundary_log(tmp_path_factory: pytest.TempPathFactory, caches: ScenarioCache) -> BoundaryLog:
    run = load_run(REFERENCE)  # its first decision, and the suite's spec of the run
    reference_spec, _ = recorded_spec(run)
    assert reference_spec.start is not None
    d, controller = next(decision_controllers(run, caches.get(load_scenario("coarse"))))
    assert not isinstance(controller, str)
    state, previous = np.array(d.state), np.zeros(3)

    def chosen(x: float) -> int:
        at = np.array([x, state[1], state[2]])
        return recompute(controller, at, previous, d.reference_index, d.first).chosen

    # The first boundary along +x across which the first decision chooses another input.
    lo = float(state[0])
    hi = next(lo + k * 0.01 for k in range(1, 40) if chosen(lo + k * 0.01) != d.chosen_index)
    lo = hi - 0.01
    below = controller.locate(np.array([lo, *state[1:]]))
    for _ in range(80):  # bisect to the last bit
        mid = 0.5 * (lo + hi)
        if controller.locate(np.array([mid, *state[1:]])) == below:
            lo = mid
        else:
            hi = mid
    # The estimate at the first decision is the start plus what the (seeded) sensor noise
    # and the first second's drift add, the same for a start moved along x (checked below).
    x0, y0, psi0 = reference_spec.start
    start = (hi - (float(state[0]) - x0) - GAP_M, y0, psi0)
    spec = dataclasses.replace(reference_spec, start=start)
    out = tmp_path_factory.mktemp("boundary")
    path = record_run(SuiteRun("boundary", spec, "first decision at a cell boundary"), out)
    first = load_run(path).decisions[0]
    assert 0 < hi - first.state[0] < BOUNDARY_TOLERANCE  # the premise: just short of it
    assert chosen(first.state[0]) != chosen(hi)  # and the other side chooses otherwise
    return BoundaryLog(path, spec, hi, first)


def _nudged(log: BoundaryLog, dx_m: float, dst: Path) -> Path:
    """Copy the log with every pose sample moved by `dx_m` along x (m)."""
    with BagReader(log.path) as reader:
        records = [r for _, _, r in reader.records()]
    edit: dict[int, Record] = {
        i: dataclasses.replace(r, x_m=r.x_m + dx_m)
        for i, r in enumerate(records)
        if isinstance(r, PoseSample)
    }
    return rewrite(log.path, dst, edit)


def test_the_unchanged_boundary_log_reproduces(
    boundary_log: BoundaryLog, caches: ScenarioCache
) -> None:
    report = replay_unmodified(boundary_log.path, caches)
    assert report.status is Status.PASS, report.regressions
    assert report.check("stack").metrics["divergence"] is None


def test_a_stack_rerun_across_a_boundary_passes_with_the_divergence_reported(
    boundary_log: BoundaryLog, caches: ScenarioCache, tmp_path: Path
) -> None:
    report = replay_unmodified(_nudged(boundary_log, NOISE_M, tmp_path / "noise"), caches)
    assert report.status is Status.PASS, report.regressions
    stack = report.check("stack")
    assert stack.status is Status.PASS
    t = boundary_log.first.t_ns
    assert stack.metrics["boundary_decisions"] == 1
    assert stack.metrics["cost_ties"] == 0
    assert stack.metrics["compared_until_ns"] == t
    divergence = stack.metrics["divergence"]
    assert divergence["kind"] == BOUNDARY
    assert divergence["replayed"]["state"][0] > boundary_log.boundary_x  # it did cross
    assert divergence["replayed"]["cell"] != divergence["recorded"]["cell"]
    # Another input chosen: every reference and command after it departs, not compared.
    assert divergence["replayed"]["chosen"] != boundary_log.first.chosen_index
    assert stack.metrics["commands"] < len(load_run(boundary_log.path).thrusters) // 10
    assert f"compared up to t={t / 1e9:.3f} s only" in stack.summary
    assert BOUNDARY in stack.summary
    (finding,) = stack.findings
    assert finding.t_ns == t
    assert "not compared after" in finding.message
    data = json.loads(summary_json([report]))
    (stack_json,) = [c for c in data["reports"][0]["checks"] if c["name"] == "stack"]
    assert stack_json["metrics"]["divergence"]["kind"] == BOUNDARY


def test_a_divergence_beyond_the_boundary_tolerance_is_a_regression(
    boundary_log: BoundaryLog, caches: ScenarioCache, tmp_path: Path
) -> None:
    report = replay_unmodified(_nudged(boundary_log, CHANGE_M, tmp_path / "change"), caches)
    assert report.status is Status.FAIL
    stack = report.check("stack")
    assert stack.status is Status.FAIL
    assert stack.metrics["divergence"] is None
    assert stack.metrics["boundary_decisions"] == 0
    first = stack.findings[0]
    assert first.t_ns == boundary_log.first.t_ns
    assert first.message.startswith("decision:")
    assert "not within 1e-09 of a cell boundary" in first.message
    # The estimates moved by 1e-7 only, within their 1e-6: the decision is what fails first
    # (the observer, fed the thrust of the other choice, departs only after it).
    estimates = [f for f in stack.findings if f.message.startswith("estimates")]
    assert all(f.t_ns is not None and f.t_ns > first.t_ns for f in estimates)
    assert report.check("decisions").status is Status.PASS  # the recording itself holds


@pytest.mark.parametrize(("dx_m", "accepted"), [(NOISE_M, True), (CHANGE_M, False)])
def test_a_resimulation_across_a_boundary(
    boundary_log: BoundaryLog, caches: ScenarioCache, tmp_path: Path, dx_m: float, accepted: bool
) -> None:
    copy = tmp_path / "boundary"
    shutil.copytree(boundary_log.path, copy)
    x, y, psi = boundary_log.spec.start or (0.0, 0.0, 0.0)
    moved = dataclasses.replace(boundary_log.spec, start=(x + dx_m, y, psi))
    (tmp_path / MANIFEST).write_text(
        json.dumps({"format": 1, "runs": {"boundary": spec_to_json(moved)}})
    )
    resim = replay_unmodified(copy, caches, resim=True, stack=False).check("resim")
    assert resim.metrics["start_from"] == f"{MANIFEST} entry"
    if accepted:
        assert resim.status is Status.PASS, resim.findings
        assert resim.metrics["boundary_decisions"] == 1
        assert resim.metrics["compared_until_ns"] == boundary_log.first.t_ns
        assert BOUNDARY in resim.summary
    else:
        assert resim.status is Status.FAIL
        assert resim.metrics["divergence"] is None
        assert resim.findings[0].t_ns == boundary_log.first.t_ns


TIE_LOG = LOGS / "coarse-high-seed2"
TIE_T_NS = 3_050_000_000
"""A recorded decision whose chosen input (87) ties in cost J with another safe one (62)."""


def _tie_decision(
    caches: ScenarioCache,
) -> tuple[Decision, int, SymbolicAdapter, NDArray[np.float64]]:
    """Return the decision at TIE_T_NS, its tie partner, its controller and previous choice."""
    run = load_run(TIE_LOG)
    previous = np.zeros(3)
    for d, controller in decision_controllers(run, caches.get(load_scenario("coarse"))):
        if d.t_ns == TIE_T_NS:
            assert not isinstance(controller, str)
            partner = next(
                i
                for i in d.safe_input_indices
                if i != d.chosen_index and is_cost_tie(controller, d.chosen_index, i, previous)
            )
            return d, partner, controller, previous
        if d.chosen_index >= 0:
            previous = np.array(d.chosen_input)
    raise AssertionError(f"no decision at {TIE_T_NS} in {TIE_LOG}")


def test_a_cost_tie_broken_the_other_way_is_explained_and_another_choice_is_not(
    caches: ScenarioCache,
) -> None:
    d, partner, controller, previous = _tie_decision(caches)
    k = d.safe_input_indices.index(partner)
    tie = dataclasses.replace(d, chosen_index=partner, chosen_input=d.safe_inputs[k])
    assert explain_divergence(d, tie, controller, previous) == TIE
    other = next(
        (i, row)
        for i, row in zip(d.safe_input_indices, d.safe_inputs, strict=True)
        if not is_cost_tie(controller, d.chosen_index, i, previous)
    )
    costlier = dataclasses.replace(d, chosen_index=other[0], chosen_input=other[1])
    assert explain_divergence(d, costlier, controller, previous) is None
    # The tie itself, but taken at a state 1e-6 m away: not rounding, not accepted.
    apart = dataclasses.replace(tie, state=(d.state[0] + 1e-6, d.state[1], d.state[2]))
    assert explain_divergence(d, apart, controller, previous) is None


def test_a_stack_rerun_breaking_a_recorded_tie_the_other_way_passes(
    caches: ScenarioCache, tmp_path: Path
) -> None:
    # The recording broke the tie the other way (its chosen input replaced by its equal-cost
    # partner); the re-run takes the current code's choice there.
    with BagReader(TIE_LOG) as reader:
        records = [r for _, _, r in reader.records()]
    index, d = next(
        (i, r) for i, r in enumerate(records) if isinstance(r, Decision) and r.t_ns == TIE_T_NS
    )
    _, partner, _, _ = _tie_decision(caches)
    k = d.safe_input_indices.index(partner)
    swapped = dataclasses.replace(d, chosen_index=partner, chosen_input=d.safe_inputs[k])
    report = replay_unmodified(rewrite(TIE_LOG, tmp_path / "tie", {index: swapped}), caches)
    assert report.check("decisions").status is Status.PASS
    assert report.check("decisions").metrics["cost_ties"] == 1
    stack = report.check("stack")
    assert stack.status is Status.PASS, stack.findings
    assert stack.metrics["cost_ties"] == 1
    assert stack.metrics["compared_until_ns"] == TIE_T_NS
    assert stack.metrics["divergence"]["replayed"]["chosen"] == d.chosen_index
    assert TIE in stack.summary
    # (The contract check judges the recorded references, flown for the original choice,
    # against the swapped one: not what this test is about.)
