"""A decision relies on a tracked obstacle's report only while it is young enough.

With obstacles that move (a speed bound above zero) the synthesis covers their motion
for ``max_report_age_s`` + tau + late after the report, so the loop re-synthesizes every
fresher report and takes no decision on an older one: the reference goes to zero
(``obstacles_stale``) until a fresh report's controller is in (``obstacles_back``), and
the decision then is a first one. Fixed obstacles never age. The controller is the
packaged coarse scenario's, held fixed, so only the loop's bookkeeping is under test.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from hil.adapters.sim import ObstacleMotion, SimConfig, SimWorld
from hil.core.records import EventLevel
from hil.core.samples import ObstacleLayout
from hil.runs.sim_run import build_runtime, default_start, synthesizer_for
from hil.runtime.assembly import LayoutSolver, SymbolicAdapter, layout_from_scenario
from hil.runtime.loop import Runtime, World
from hil.runtime.resynthesis import ResynthesisMode
from hil.runtime.settings import NS_PER_S, LoopConfig
from hil.runtime.trace import MemoryLog
from hil.scenarios import Scenario, load_scenario

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


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory) -> tuple[Scenario, SymbolicAdapter, Path]:
    folder = tmp_path_factory.mktemp("obstacle-age")
    scenario = load_scenario("coarse")
    synthesizer = synthesizer_for(scenario, folder / "tables")
    adapter = LayoutSolver(scenario, synthesizer)(layout_from_scenario(scenario))
    return scenario, adapter, folder


def _run(setup: tuple[Scenario, SymbolicAdapter, Path], speed_mps: float,
         ) -> tuple[Runtime, MemoryLog, list[ObstacleLayout]]:
    coarse, adapter, folder = setup
    scenario = dataclasses.replace(
        coarse, obstacles=tuple(dataclasses.replace(o, max_speed_mps=speed_mps)
                                for o in coarse.obstacles))
    # A still obstacle, re-reported every second as a tracker does.
    sim = SimWorld(SimConfig(start=default_start(scenario), seed=1,
                             obstacles=layout_from_scenario(scenario).obstacles,
                             motions=(ObstacleMotion(0, (0.0, 0.0), 0.0, 0.0),)),
                   max_duration_s=24.0)
    world = World(sim.clock, sim.pose, sim.imu, _SilentTracker(sim), sim.thrusters)
    log = MemoryLog()
    solved: list[ObstacleLayout] = []

    def solve(layout: ObstacleLayout) -> SymbolicAdapter:
        solved.append(layout)
        return adapter

    runtime = build_runtime(
        scenario, world, log, LoopConfig(max_duration_s=14.0),
        synthesizer_for(scenario, folder / "tables"), ResynthesisMode.INLINE, solver=solve,
    )
    runtime.run()
    return runtime, log, solved


def test_a_report_older_than_the_max_age_stops_decisions_until_a_fresh_one(
    setup: tuple[Scenario, SymbolicAdapter, Path],
) -> None:
    runtime, log, solved = _run(setup, 0.05)
    assert runtime.obstacle_max_age_s == 1.0  # the coarse scenario's max_report_age_s
    # Every fresher report was synthesized (a still obstacle too): one per second but
    # for the silent span.
    stamps_s = sorted({layout.t_ns / NS_PER_S for layout in solved})
    assert stamps_s == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 10.0, 11.0, 12.0, 13.0, 14.0]
    events = [(level, code) for _, level, code, _ in log.events if code.startswith("obstacles_")]
    at_s = [t / NS_PER_S for t, _, code, _ in log.events if code.startswith("obstacles_")]
    # The decision due at 7.05 s would rely on the 5-s report, 2.05 s old: stopped; the
    # 10-s report's controller lets it be taken at once.
    assert events == [(EventLevel.ERROR, "obstacles_stale"), (EventLevel.INFO, "obstacles_back")]
    assert at_s == pytest.approx([7.05, 10.0])
    assert runtime.stats.obstacle_stale_stops == 1
    times_s = [d.t_ns / NS_PER_S for d in log.decisions]
    assert times_s[:4] == pytest.approx([1.05, 3.05, 5.05, 10.0])
    assert log.decisions[3].first
    assert not log.decisions[2].first
    for d in log.decisions:  # no decision relied on a report older than 1 s
        newest = max(t for t in (layout.t_ns for layout in solved) if t <= d.t_ns)
        assert d.t_ns - newest <= NS_PER_S
    # Stopped meanwhile: the velocity reference is zero from the stale decision on.
    held = [ref for t, ref in log.velocity_references if 7.05 * NS_PER_S <= t < 10 * NS_PER_S]
    assert held
    assert np.all(np.array(held) == 0.0)
    assert np.any(np.array(log.velocity_references[-1][1]) != 0.0)  # going again


def test_fixed_obstacles_never_age(setup: tuple[Scenario, SymbolicAdapter, Path]) -> None:
    runtime, log, solved = _run(setup, 0.0)
    assert runtime.obstacle_max_age_s is None
    assert not [c for c in log.event_codes() if c.startswith("obstacles_")]
    times_s = [d.t_ns / NS_PER_S for d in log.decisions]
    assert times_s[:5] == pytest.approx([1.05, 3.05, 5.05, 7.05, 9.05])
    # Re-synthesized on the 2-s timer only (0, 2, ..., 14 s), whatever the tracker's stamps.
    assert len(solved) == 8
