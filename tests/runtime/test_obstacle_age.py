"""A decision relies on a tracked obstacle's report only while it is young enough.

With obstacles that move (a speed bound above zero) the synthesis covers their motion
for ``max_report_age_s`` + tau + late after the report, so the loop re-synthesizes a
fresher report of moved obstacles, renews the report time of the controller in force on
a fresher report of the same shapes (no synthesis, no new controller version), and takes
no decision on a report older than that: the reference goes to zero (``obstacles_stale``)
until a fresh report is in (``obstacles_back``), and the decision then is a first one.
Every report taken in is recorded, so a replay sees the report each decision relied on.
Fixed obstacles never age. The controller is the packaged coarse scenario's, held fixed,
so only the loop's bookkeeping is under test.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from hil.adapters.sim import ObstacleMotion, SimConfig, SimWorld
from hil.controllers.symbolic import SymbolicAdapter
from hil.core.records import EventLevel
from hil.core.samples import ObstacleLayout
from hil.runs.stack_assembly import build_runtime, default_start, synthesizer_for
from hil.runtime.assembly import layout_from_scenario
from hil.runtime.loop import Runtime, World
from hil.runtime.protocols import SymbolicController
from hil.runtime.resynthesis import ResynthesisMode, Resynthesizer, VesselState
from hil.runtime.settings import NS_PER_S, LoopConfig
from hil.runtime.trace import MemoryLog
from hil.scenarios import Scenario

SILENT_S = (6.0, 10.0)  # the tracker reports nothing in [6, 10) s


class _SilentTracker:
    """The simulated tracker, silent over `SILENT_S`: the last report before stays newest."""

    def __init__(self, sim: SimWorld) -> None:
        self._sim = sim
        self._last: ObstacleLayout | None = None

    def latest(self) -> ObstacleLayout:
        t_s = self._sim.clock.now_ns() / NS_PER_S
        if self._last is None or not SILENT_S[0] <= t_s < SILENT_S[1]:
            self._last = self._sim.obstacles.latest()
        return self._last


STILL = ObstacleMotion(0, (0.0, 0.0), 0.0, 0.0)
"""O2 still, re-reported every second as a tracker does."""
MOVED = ObstacleMotion(0, (0.0, -0.05), 2.0, 4.0)
"""O2 moving down 5 cm a second over [2, 4] s: its 3-s and 4-s reports are moved shapes."""
REPORTS_S = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 10.0, 11.0, 12.0, 13.0, 14.0]
"""The reports the loop takes in: one a second but for the silent span."""


def _run(setup: tuple[Scenario, SymbolicAdapter, Path], speed_mps: float,
         motion: ObstacleMotion = STILL, resynthesis_period_s: float | None = 2.0,
         ) -> tuple[Runtime, MemoryLog, list[ObstacleLayout]]:
    coarse, adapter, folder = setup
    scenario = dataclasses.replace(
        coarse, obstacles=tuple(dataclasses.replace(o, max_speed_mps=speed_mps)
                                for o in coarse.obstacles))
    sim = SimWorld(SimConfig(start=default_start(scenario), seed=1,
                             obstacles=layout_from_scenario(scenario).obstacles,
                             motions=(motion,)),
                   max_duration_s=24.0)
    world = World(sim.clock, sim.pose, sim.imu, _SilentTracker(sim), sim.thrusters)
    log = MemoryLog()
    solved: list[ObstacleLayout] = []

    def solve(layout: ObstacleLayout, report_age_s: float) -> SymbolicAdapter:
        solved.append(layout)
        return adapter

    runtime = build_runtime(
        scenario, world, log,
        LoopConfig(max_duration_s=14.0, resynthesis_period_s=resynthesis_period_s),
        synthesizer_for(scenario, folder / "tables"), ResynthesisMode.INLINE, solver=solve,
    )
    runtime.run()
    return runtime, log, solved


def _assert_stale_over_the_silent_span(runtime: Runtime, log: MemoryLog) -> None:
    """The decisions of a run whose tracker is silent over `SILENT_S`, as before renewals."""
    events = [(level, code) for _, level, code, _ in log.events if code.startswith("obstacles_")]
    at_s = [t / NS_PER_S for t, _, code, _ in log.events if code.startswith("obstacles_")]
    # The decision due at 7.05 s would rely on the 5-s report, 2.05 s old: stopped; the
    # 10-s report lets it be taken at once.
    assert events == [(EventLevel.ERROR, "obstacles_stale"), (EventLevel.INFO, "obstacles_back")]
    assert at_s == pytest.approx([7.05, 10.0])
    assert runtime.stats.obstacle_stale_stops == 1
    times_s = [d.t_ns / NS_PER_S for d in log.decisions]
    assert times_s[:4] == pytest.approx([1.05, 3.05, 5.05, 10.0])
    assert log.decisions[3].first
    assert not log.decisions[2].first
    # Every report taken in is recorded, renewals too: the replay's stack re-run reads the
    # report each decision relied on from this stream.
    # (Up to the 14-s limit: the run then brakes to rest, still recording reports.)
    taken = [layout.t_ns / NS_PER_S for layout in log.layouts]
    assert [t for t in taken if t <= 14.0] == REPORTS_S
    for d in log.decisions:  # no decision relied on a report older than 1 s
        newest = max(t for t in (layout.t_ns for layout in log.layouts) if t <= d.t_ns)
        assert d.t_ns - newest <= NS_PER_S
    # Stopped meanwhile: the velocity reference is zero from the stale decision on.
    held = [ref for t, ref in log.velocity_references if 7.05 * NS_PER_S <= t < 10 * NS_PER_S]
    assert held
    assert np.all(np.array(held) == 0.0)
    before_limit = [ref for t, ref in log.velocity_references if t <= 14 * NS_PER_S]
    assert np.any(np.array(before_limit[-1]) != 0.0)  # going again (braking after the limit)


def test_a_report_older_than_the_max_age_stops_decisions_until_a_fresh_one(
    setup: tuple[Scenario, SymbolicAdapter, Path],
) -> None:
    runtime, log, solved = _run(setup, 0.05)
    assert runtime.report_ages.next_s() == 1.0  # the coarse scenario's max_report_age_s
    # A fresher report of the still obstacle renews the stamp, it is not synthesized: the
    # syntheses are the 2-s timer's (0, 2, ..., 14 s) as with fixed obstacles, each of the
    # newest report then (the 5-s one at 6 and 8 s, the tracker silent).
    assert [layout.t_ns / NS_PER_S for layout in solved] == [
        0.0, 2.0, 4.0, 5.0, 5.0, 10.0, 12.0, 14.0]
    _assert_stale_over_the_silent_span(runtime, log)
    # The controller relies on the last report, renewed at 13 s and synthesized at 14 s.
    assert runtime.slot.layout is not None
    assert runtime.slot.layout.t_ns == log.layouts[-1].t_ns  # renewed to the last report


def test_a_fresher_report_of_the_same_shapes_renews_the_stamp_without_synthesis(
    setup: tuple[Scenario, SymbolicAdapter, Path],
) -> None:
    # No timer: only a change of the shapes is synthesized.
    runtime, log, solved = _run(setup, 0.05, resynthesis_period_s=None)
    assert [layout.t_ns for layout in solved] == [0]
    assert runtime.stats.resyntheses == 1
    assert runtime.controller_version == 1
    assert {d.controller_version for d in log.decisions} == {1}
    assert log.event_codes().count("controller_ready") == 1
    # The one controller's report time followed the reports: the 10-s report, of the same
    # shapes, was enough to decide again, and the last one (14 s) is the one relied on.
    _assert_stale_over_the_silent_span(runtime, log)
    assert runtime.slot.layout is not None
    assert runtime.slot.layout.t_ns == log.layouts[-1].t_ns  # renewed to the last report
    assert runtime.slot.layout.obstacles == solved[0].obstacles


def test_a_moved_obstacle_is_still_synthesized(
    setup: tuple[Scenario, SymbolicAdapter, Path],
) -> None:
    runtime, log, solved = _run(setup, 0.05, MOVED, resynthesis_period_s=None)
    # The 3-s and 4-s reports moved O2 (by 5 cm each): a synthesis each, a new version.
    assert [layout.t_ns / NS_PER_S for layout in solved] == [0.0, 3.0, 4.0]
    assert [layout.obstacles[0].y_min_m for layout in solved] == pytest.approx(
        [solved[0].obstacles[0].y_min_m - dy for dy in (0.0, 0.05, 0.1)])
    assert runtime.controller_version == 3
    assert [d.t_ns / NS_PER_S for d in log.decisions[:3]] == pytest.approx([1.05, 3.05, 5.05])
    versions = [d.controller_version for d in log.decisions]
    assert versions[:3] == [1, 2, 3]
    assert set(versions[3:]) == {3}  # the later reports only renewed its stamp
    _assert_stale_over_the_silent_span(runtime, log)
    assert runtime.slot.layout is not None
    assert runtime.slot.layout.t_ns == log.layouts[-1].t_ns  # renewed to the last report
    assert runtime.slot.layout.obstacles == solved[-1].obstacles


class _Deferred(Resynthesizer[SymbolicController]):
    """A resynthesizer whose syntheses finish only when told (as a thread's would, later)."""

    def __init__(self, solve: Callable[[ObstacleLayout, float], SymbolicController]) -> None:
        super().__init__(solve, ResynthesisMode.INLINE)
        self.held: list[tuple[ObstacleLayout, float]] = []

    @property
    def busy(self) -> bool:
        return bool(self.held)

    def submit(
        self, layout: ObstacleLayout, report_age_s: float, vessel: VesselState | None = None
    ) -> None:
        self.held.append((layout, report_age_s))

    def finish(self) -> None:
        for layout, age in self.held:
            super().submit(layout, age)
        self.held.clear()


class _Reports:
    """An obstacle source serving whatever report the test set last."""

    def __init__(self, layout: ObstacleLayout) -> None:
        self.layout = layout

    def latest(self) -> ObstacleLayout:
        return self.layout


def _deferred_runtime(
    setup: tuple[Scenario, SymbolicAdapter, Path],
) -> tuple[Runtime, _Deferred, _Reports, MemoryLog]:
    """A runtime on coarse with O1 and O2 tracked at 0.05 m/s, its syntheses held back.

    The reports start with the still layout stamped 1 s; the test steps the loop's
    obstacle bookkeeping by hand.
    """
    coarse, adapter, folder = setup
    scenario = dataclasses.replace(
        coarse, obstacles=tuple(dataclasses.replace(o, max_speed_mps=0.05)
                                for o in coarse.obstacles))
    still = layout_from_scenario(scenario).obstacles
    sim = SimWorld(SimConfig(start=default_start(scenario), seed=1, obstacles=still))
    reports = _Reports(ObstacleLayout(1 * NS_PER_S, still))
    world = World(sim.clock, sim.pose, sim.imu, reports, sim.thrusters)
    log = MemoryLog()
    runtime = build_runtime(
        scenario, world, log, LoopConfig(resynthesis_period_s=None),
        synthesizer_for(scenario, folder / "tables"), ResynthesisMode.INLINE,
        solver=lambda layout, age: adapter,
    )
    deferred = _Deferred(lambda layout, age: adapter)
    runtime.slot.resynthesizer = deferred
    return runtime, deferred, reports, log


def test_a_synthesis_finishing_after_a_renewal_keeps_the_renewed_stamp(
    setup: tuple[Scenario, SymbolicAdapter, Path],
) -> None:
    runtime, deferred, reports, log = _deferred_runtime(setup)
    still = reports.layout.obstacles

    def step(t_s: float) -> None:
        runtime.slot.watch(round(t_s * NS_PER_S), False, lambda: None)
        runtime.slot.swap(round(t_s * NS_PER_S))

    step(1.0)  # the 1-s report: submitted, being solved
    assert [layout.t_ns for layout, _ in deferred.held] == [NS_PER_S]
    reports.layout = ObstacleLayout(2 * NS_PER_S, still)
    step(2.0)  # the same shapes, fresher: renewed, not submitted
    assert [layout.t_ns for layout, _ in deferred.held] == [NS_PER_S]
    deferred.finish()
    step(2.5)  # the 1-s synthesis is in: it relies on the renewed 2-s report
    assert runtime.controller_version == 1
    assert runtime.slot.layout == ObstacleLayout(2 * NS_PER_S, still)
    reports.layout = ObstacleLayout(3 * NS_PER_S, still)
    step(3.0)  # renewed in force: no synthesis, the same version
    assert not deferred.held
    assert runtime.controller_version == 1
    assert runtime.slot.layout == ObstacleLayout(3 * NS_PER_S, still)
    moved = (still[0].translate(0.0, -0.05), *still[1:])
    reports.layout = ObstacleLayout(4 * NS_PER_S, moved)
    step(4.0)  # moved: submitted; the controller in force keeps its own report
    assert [layout for layout, _ in deferred.held] == [ObstacleLayout(4 * NS_PER_S, moved)]
    reports.layout = ObstacleLayout(5 * NS_PER_S, moved)
    step(5.0)  # a renewal of the moved shapes leaves the still ones' report as it was
    assert runtime.slot.layout == ObstacleLayout(3 * NS_PER_S, still)
    deferred.finish()
    step(5.5)
    assert runtime.controller_version == 2
    assert runtime.slot.layout == ObstacleLayout(5 * NS_PER_S, moved)
    # Every report was recorded, renewals too.
    assert [layout.t_ns / NS_PER_S for layout in log.layouts] == [1.0, 2.0, 3.0, 4.0, 5.0]


def test_a_controller_arriving_older_than_the_max_age_is_named(
    setup: tuple[Scenario, SymbolicAdapter, Path],
) -> None:
    runtime, deferred, reports, log = _deferred_runtime(setup)
    still = reports.layout.obstacles
    moved = (still[0].translate(0.0, -0.05), *still[1:])
    assert runtime.report_ages.next_s() == 1.0

    def step(t_s: float) -> list[str]:
        runtime.slot.watch(round(t_s * NS_PER_S), False, lambda: None)
        runtime.slot.swap(round(t_s * NS_PER_S))
        return [text for _, _, code, text in log.events if code == "synthesis_overrun"]

    step(1.0)
    deferred.finish()
    assert step(1.5) == []  # 0.5 s after its report: in time
    reports.layout = ObstacleLayout(2 * NS_PER_S, moved)
    step(2.0)  # moved: submitted; the solver takes 1.5 s
    deferred.finish()
    warned = step(3.5)
    assert len(warned) == 1
    assert "controller v2 arrived 1.50 s after its obstacle report" in warned[0]
    assert "older than the 1 s it was solved for" in warned[0]
    assert 'report_age = "measured"' in warned[0]  # the remedy, named
    assert runtime.controller_version == 2
    reports.layout = ObstacleLayout(4 * NS_PER_S, moved)
    assert len(step(4.0)) == 1  # a fresher report of its shapes renews it: nothing new
    assert runtime.slot.layout == ObstacleLayout(4 * NS_PER_S, moved)


def test_fixed_obstacles_never_age(setup: tuple[Scenario, SymbolicAdapter, Path]) -> None:
    runtime, log, solved = _run(setup, 0.0)
    assert not runtime.report_ages.tracks
    assert not [c for c in log.event_codes() if c.startswith("obstacles_")]
    times_s = [d.t_ns / NS_PER_S for d in log.decisions]
    assert times_s[:5] == pytest.approx([1.05, 3.05, 5.05, 7.05, 9.05])
    # Re-synthesized on the 2-s timer only (0, 2, ..., 14 s), whatever the tracker's stamps.
    assert len(solved) == 8
