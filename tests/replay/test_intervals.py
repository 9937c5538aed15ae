"""The run judged interval by interval: containment, tracking error, verdict."""

from __future__ import annotations

import numpy as np

from hil.bag.run_data import load_run
from hil.replay.controllers import ScenarioCache, resolve_scenario
from hil.replay.decisions import decision_controllers
from hil.replay.intervals import judge_intervals, successor_contained, tube_contained
from hil.replay.regression import Check, Finding, Status
from hil.runtime.assembly import SymbolicAdapter
from tests.replay.suite_logs import REFERENCE


def test_where_the_margin_held_the_abstraction_contains_the_recorded_motion(
    caches: ScenarioCache,
) -> None:
    run = load_run(REFERENCE)
    scenario = resolve_scenario(run)
    intervals = judge_intervals(run, caches.get(scenario), scenario, [])
    assert [i.t_ns for i in intervals] == [d.t_ns for d in run.decisions]
    judged = [i for i in intervals if i.successor_contained is not None]
    assert len(judged) > len(intervals) // 2
    # The synthesis assumed the tracking error within the margin: where it was, the
    # state after tau is in the successor cells and the path in the swept tube.
    held = [i for i in judged if not i.margin_exceeded]
    assert held
    assert all(i.successor_contained and i.tube_contained for i in held)
    assert all(i.status is Status.PASS for i in held)
    assert all(i.status is Status.WARN for i in intervals if i.margin_exceeded)
    rms = [i.tracking_rms for i in intervals if i.tracking_rms is not None]
    assert rms
    assert all(v >= 0 for r in rms for v in r)


def test_a_state_far_away_is_not_contained(caches: ScenarioCache) -> None:
    run = load_run(REFERENCE)
    controllers = caches.get(resolve_scenario(run))
    d, adapter = next(
        (d, a)
        for d, a in decision_controllers(run, controllers)
        if isinstance(a, SymbolicAdapter) and d.chosen_index >= 0
    )
    assert isinstance(adapter, SymbolicAdapter)
    far = np.array(d.state) + np.array([1.0, 1.0, 0.0])
    assert successor_contained(adapter, d, far) is False
    assert tube_contained(adapter, d, np.array([d.state, far])) is False
    assert tube_contained(adapter, d, np.array([d.state])) is True  # the start is in its tube


def test_a_failed_check_marks_the_interval_it_names(caches: ScenarioCache) -> None:
    run = load_run(REFERENCE)
    scenario = resolve_scenario(run)
    t = run.decisions[5].t_ns + 1
    failed = Check("stack", Status.FAIL, "x", (Finding("differs", t),))
    intervals = judge_intervals(run, caches.get(scenario), scenario, [failed])
    assert [i.status is Status.FAIL for i in intervals].count(True) == 1
    assert intervals[5].status is Status.FAIL
    assert intervals[5].notes[0] == "a failed check names a time in this interval"
