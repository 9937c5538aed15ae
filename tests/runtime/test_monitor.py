"""The runtime monitor: the estimate held to the decision in force, and the loop's reaction.

A simulated run on the packaged coarse scenario (a winning set under its measured
transient budget) keeps every contract: no monitor event. The
same run with the observer's estimate pushed sideways mid-interval leaves the tube:
a TUBE_EXIT event with the distance the contract's own judge measures, and a first
decision at that very tick; pushed into an obstacle, the re-decision finds nothing
safe and the vessel is stopped as on any not-winning state.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.adapters.sim import SimConfig, SimWorld
from hil.controllers.consistency import ConsistencyBreach
from hil.controllers.symbolic import DecisionContract, SymbolicAdapter
from hil.core.records import EventLevel
from hil.core.samples import ImuSample, ObstacleLayout, PoseSample
from hil.runs.guarantee import judge_run
from hil.runs.stack_assembly import build_runtime, default_start, synthesizer_for
from hil.runtime.assembly import EkfObserver, layout_from_scenario
from hil.runtime.loop import Runtime, World
from hil.runtime.monitor import Monitor
from hil.runtime.resynthesis import ResynthesisMode
from hil.runtime.settings import NS_PER_S, LoopConfig
from hil.runtime.trace import MemoryLog
from hil.scenarios import Scenario
from hil.sim.plant import TR_ETA

FloatArray = NDArray[np.float64]
Shift = Callable[[int, FloatArray], FloatArray]

MONITOR_CODES = {"tube_exit", "successor_miss", "value_not_decreasing"}


class _ShiftedObserver:
    """The EKF, its estimated pose passed through `shift(t_ns, eta)` (a scripted fault)."""

    def __init__(self, shift: Shift) -> None:
        self.ekf = EkfObserver()
        self.shift = shift
        self.t_ns = 0

    def update_pose(self, sample: PoseSample) -> bool:
        self.t_ns = max(self.t_ns, sample.t_ns)
        return self.ekf.update_pose(sample)

    def update_imu(self, sample: ImuSample) -> bool:
        return self.ekf.update_imu(sample)

    def breach(self) -> ConsistencyBreach | None:
        return self.ekf.breach()

    def estimate(self) -> tuple[FloatArray, FloatArray] | None:
        got = self.ekf.estimate()
        if got is None:
            return None
        return self.shift(self.t_ns, got[0].copy()), got[1]


def _run(
    setup: tuple[Scenario, SymbolicAdapter, Path], duration_s: float, shift: Shift | None = None
) -> tuple[Runtime, MemoryLog, SimWorld]:
    scenario, adapter, folder = setup
    sim = SimWorld(
        SimConfig(start=default_start(scenario), seed=1,
                  obstacles=layout_from_scenario(scenario).obstacles),
        max_duration_s=duration_s + 10.0,
    )
    world = World(sim.clock, sim.pose, sim.imu, sim.obstacles, sim.thrusters)
    log = MemoryLog()

    def solve(_layout: ObstacleLayout, _report_age_s: float) -> SymbolicAdapter:
        return adapter

    runtime = build_runtime(
        scenario, world, log, LoopConfig(resynthesis_period_s=None, max_duration_s=duration_s),
        synthesizer_for(scenario, folder / "tables"), ResynthesisMode.INLINE, solver=solve,
    )
    if shift is not None:
        runtime.observer = _ShiftedObserver(shift)
    runtime.run()
    return runtime, log, sim


def test_a_clean_run_raises_no_monitor_event(
    setup: tuple[Scenario, SymbolicAdapter, Path],
) -> None:
    scenario, adapter, _ = setup
    runtime, log, sim = _run(setup, 30.0)
    assert runtime.stats.decisions >= 14
    assert not MONITOR_CODES & set(log.event_codes())
    s = runtime.stats
    assert (s.tube_exits, s.successor_misses, s.value_not_decreasing) == (0, 0, 0)
    # The campaign's judge agrees on the true state: the budget held in this run.
    truth = sim.truth()
    judged = judge_run(scenario, log.decisions, {1: adapter.controller}, truth[:, 0],
                       truth[:, 1 + TR_ETA : 1 + TR_ETA + 3])
    assert judged.tube_exits == judged.successor_misses == judged.value_not_decreasing == 0


def test_an_estimate_pushed_out_of_the_tube_is_reported_and_redecided(
    setup: tuple[Scenario, SymbolicAdapter, Path],
) -> None:
    scenario, adapter, _ = setup
    at_ns = 6 * NS_PER_S  # 0.95 s into the interval decided at 5.05 s (after 1 s settling)

    def push(t_ns: int, eta: FloatArray) -> FloatArray:
        if t_ns >= at_ns:
            eta[0] -= 0.6
        return eta

    runtime, log, _ = _run(setup, 10.0, push)
    exits = [e for e in log.events if e[2] == "tube_exit"]
    assert len(exits) == 1
    t_ns, level, _, text = exits[0]
    assert level is EventLevel.ERROR
    assert at_ns <= t_ns <= at_ns + 60_000_000  # the first tick that sees the push
    # The size is what the decision's contract measures for the recorded estimate.
    before = [d for d in log.decisions if d.t_ns < t_ns][-1]
    assert before.t_ns == 5_050_000_000
    assert not before.first  # a regular decision (a start counts two first ones)
    assert "decision at t=5.050 s" in text
    contract = DecisionContract.of(
        adapter.controller,
        adapter.controller.grid.cell_of(before.state),  # type: ignore[arg-type]
        before.chosen_index, before.reference_index, before.first,
    )
    estimate = next(e for t, e, _ in log.estimates if t == t_ns)
    size = float(contract.tube_distance_m(np.asarray(estimate)[None, :])[0])
    assert size > scenario.transient.estimation_position_m
    match = re.search(r"estimate (\d+\.\d+) m from the tube", text)
    assert match is not None
    assert float(match.group(1)) == pytest.approx(size, abs=1e-4)
    assert runtime.stats.tube_exits == 1
    assert runtime.stats.worst_tube_exit_m == pytest.approx(size)
    # The reaction: a first decision at the same tick, from the estimated velocity.
    redecided = next(d for d in log.decisions if d.t_ns == t_ns)
    assert redecided.first
    assert redecided.chosen_index >= 0
    # The next regular decision is a period later, and the shifted estimate, now steady,
    # keeps the new contract.
    after = [d.t_ns for d in log.decisions if d.t_ns > t_ns]
    assert after
    assert after[0] == t_ns + 2 * NS_PER_S


def test_a_tube_exit_into_an_obstacle_stops_the_vessel(
    setup: tuple[Scenario, SymbolicAdapter, Path],
) -> None:
    at_ns = 2 * NS_PER_S  # mid-interval of the first decision (1.05 s, after settling)

    def jump(t_ns: int, eta: FloatArray) -> FloatArray:
        return np.array([-1.0, 1.5, eta[2]]) if t_ns >= at_ns else eta  # inside O2

    runtime, log, _ = _run(setup, 10.0, jump)
    codes = log.event_codes()
    assert codes.index("tube_exit") < codes.index("not_winning")
    exit_t = next(t for t, _, c, _ in log.events if c == "tube_exit")
    redecided = next(d for d in log.decisions if d.t_ns == exit_t)
    assert redecided.first
    assert redecided.chosen_index == -1
    assert np.all(np.array(redecided.chosen_input) == 0.0)  # stopped
    assert runtime.stats.aborted  # still not winning a period later
    assert runtime.stats.tube_exits == 1


def test_the_judges_cost_little_per_tick(
    setup: tuple[Scenario, SymbolicAdapter, Path],
) -> None:
    _, adapter, _ = setup
    state = np.array(default_start(setup[0]))
    idx = adapter.safe_input_indices(state, adapter.nearest_input(np.zeros(3)), True)
    contract = adapter.contract(state, int(idx[0]), adapter.nearest_input(np.zeros(3)), True)
    assert contract is not None
    monitor = Monitor(0.002)
    monitor.start(0, contract)
    n = 500
    start = time.perf_counter()
    for k in range(n):
        monitor.tick(k * 50_000_000 // 25, state)
    per_tick = (time.perf_counter() - start) / n
    assert per_tick < 1e-3  # under 2 % of a 50-ms tick (typically ~20 us)
