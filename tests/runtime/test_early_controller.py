"""A new layout's early controller is put in force where it covers the vessel's state.

On the vessel a re-synthesis runs beside the loop and hands out an early controller as
soon as the vessel's (cell, reference) joined, then the full one under the same version
(:mod:`hil.runtime.resynthesis`). The loop must say where the vessel is when it submits a
layout mid-run, take the early controller for a non-first decision only where it covers
the state, and not before it arrives; the full one replaces it. The syntheses here are
scripted on the simulated clock (the coarse scenario's controller, held fixed), so only
the loop's bookkeeping is under test; the early controller's exactness is tested with
the solver (tests/controllers/symbolic/test_early_stop.py).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hil.adapters.sim import SimConfig, SimWorld
from hil.controllers.symbolic import SymbolicAdapter
from hil.core.samples import ObstacleLayout
from hil.runs.stack_assembly import build_runtime, default_start, synthesizer_for
from hil.runtime.assembly import layout_from_scenario
from hil.runtime.loop import Runtime, World
from hil.runtime.protocols import SymbolicController
from hil.runtime.resynthesis import (
    ResynthesisMode,
    Resynthesizer,
    SynthesisResult,
    VesselState,
)
from hil.runtime.settings import NS_PER_S, LoopConfig
from hil.runtime.trace import MemoryLog
from hil.scenarios import Scenario
from hil.sim.sensors import PoseSensorConfig

FloatArray = NDArray[np.float64]

FULL_AFTER_S = 3.0
"""The scripted full solve ends this long after the early controller (simulated s)."""


class _Blind(SymbolicAdapter):
    """A controller that covers no state (as an early one solved to a lower level)."""

    def value(self, state: FloatArray, reference: int, first: bool) -> float:
        return math.inf


Result = SynthesisResult[SymbolicController]


class _Scripted(Resynthesizer[SymbolicController]):
    """Syntheses on the simulated clock: the first mid-run one comes early, then full.

    A submission without a vessel state (start) is solved at once. The first one with a
    vessel state posts `early` at once and the full controller FULL_AFTER_S later; later
    ones are solved at once.
    """

    def __init__(
        self, sim: SimWorld, full: SymbolicAdapter, early: SymbolicAdapter, full_after_s: float
    ) -> None:
        super().__init__(lambda layout, age: full, ResynthesisMode.INLINE)
        self._sim = sim
        self._full = full
        self._early = early
        self.vessels: list[VesselState] = []
        self._queue: list[tuple[int, SynthesisResult[SymbolicController]]] = []
        self._versions = 0
        self.full_due_ns: int | None = None
        self._full_after_ns = round(full_after_s * NS_PER_S)

    @property
    def busy(self) -> bool:
        return bool(self._queue)

    def submit(
        self, layout: ObstacleLayout, report_age_s: float, vessel: VesselState | None = None
    ) -> None:
        self._versions += 1
        now = self._sim.clock.now_ns()
        v = self._versions
        if vessel is None or self.vessels:
            full: Result = SynthesisResult(v, layout, report_age_s, self._full, None, 0.0)
            self._queue.append((now, full))
            return
        self.vessels.append(vessel)
        self.full_due_ns = now + self._full_after_ns
        early: Result = SynthesisResult(v, layout, report_age_s, self._early, None, 0.5, False)
        self._queue.append((now, early))
        full = SynthesisResult(v, layout, report_age_s, self._full, None, 3.5)
        self._queue.append((self.full_due_ns, full))

    def poll(self) -> SynthesisResult[SymbolicController] | None:
        now = self._sim.clock.now_ns()
        due = [r for t, r in self._queue if t <= now]
        if not due:
            return None
        self._queue = [(t, r) for t, r in self._queue if t > now]
        return due[0]  # one result per tick, in order: an early one is seen before its full


def _run(
    setup: tuple[Scenario, SymbolicAdapter, Path],
    early: SymbolicAdapter | None = None,
    full_after_s: float = FULL_AFTER_S,
    pose_outages_s: tuple[tuple[float, float], ...] = (),
) -> tuple[Runtime, _Scripted, MemoryLog]:
    scenario, adapter, folder = setup
    sim = SimWorld(
        SimConfig(
            start=default_start(scenario),
            seed=3,
            obstacles=layout_from_scenario(scenario).obstacles,
            pose=PoseSensorConfig(scheduled_dropouts_s=pose_outages_s),
        ),
        max_duration_s=20.0,
    )
    world = World(sim.clock, sim.pose, sim.imu, sim.obstacles, sim.thrusters)
    log = MemoryLog()
    runtime = build_runtime(
        scenario,
        world,
        log,
        LoopConfig(max_duration_s=12.0, resynthesis_period_s=2.0),
        synthesizer_for(scenario, folder / "tables"),
        ResynthesisMode.INLINE,
        solver=lambda layout, age: adapter,
    )
    scripted = _Scripted(sim, adapter, adapter if early is None else early, full_after_s)
    runtime.slot.resynthesizer = scripted
    runtime.run()
    return runtime, scripted, log


def test_a_covering_early_controller_decides_before_the_full_solve_ends(
    setup: tuple[Scenario, SymbolicAdapter, Path],
) -> None:
    runtime, scripted, log = _run(setup)
    # The first submission after the start's first decisions says where the vessel is.
    assert len(scripted.vessels) == 1
    vessel = scripted.vessels[0]
    assert scripted.full_due_ns is not None
    submitted_at = scripted.full_due_ns - round(FULL_AFTER_S * NS_PER_S)
    estimates = [(t, eta) for t, eta, _ in log.estimates if t <= submitted_at]
    np.testing.assert_array_equal(vessel.eta, estimates[-1][1])
    before = [d for d in log.decisions if d.t_ns <= submitted_at]
    assert vessel.reference == before[-1].chosen_index  # the reference in force
    early_version = next(d.controller_version for d in log.decisions if d.t_ns > submitted_at)
    texts = [text for _, _, code, text in log.events if code == "controller_ready"]
    assert any(text.startswith(f"controller v{early_version} early in") for text in texts)
    # Decided on before its full solve was in, as a non-first decision.
    early_decisions = [
        d
        for d in log.decisions
        if d.controller_version == early_version and d.t_ns < scripted.full_due_ns
    ]
    assert early_decisions
    assert not any(d.first for d in early_decisions)
    assert runtime.stats.early_controllers == 1


def test_an_early_controller_that_does_not_cover_the_state_is_not_taken(
    setup: tuple[Scenario, SymbolicAdapter, Path],
) -> None:
    _, adapter, _ = setup
    runtime, scripted, log = _run(setup, early=_Blind(adapter.controller))
    full_due_ns = scripted.full_due_ns
    assert full_due_ns is not None
    versions_before_full = {d.controller_version for d in log.decisions if d.t_ns < full_due_ns}
    early_version = max(d.controller_version for d in log.decisions)
    assert early_version not in versions_before_full  # the old controller decided meanwhile
    assert runtime.stats.early_controllers == 0
    assert not any(d.value == math.inf for d in log.decisions)


def test_a_first_decision_under_an_early_controller_waits_for_the_full_solve(
    setup: tuple[Scenario, SymbolicAdapter, Path],
) -> None:
    # The early controller comes at 4 s and decides at 5.05 s; the pose is lost over
    # [5.5, 6.0) s, so the next decision is a first one (at rest layer, any value): only
    # the full solve, due at 10 s, may take it.
    runtime, scripted, log = _run(setup, full_after_s=6.0, pose_outages_s=((5.5, 0.5),))
    full_due_ns = scripted.full_due_ns
    assert full_due_ns is not None
    assert runtime.stats.early_controllers == 1
    assert runtime.stats.pose_losses == 1
    back_ns = next(t for t, _, code, _ in log.events if code == "pose_back")
    assert back_ns < full_due_ns - 2 * NS_PER_S  # the filter settled well before the full one
    waited = [d for d in log.decisions if back_ns <= d.t_ns < full_due_ns]
    assert waited == []
    after = [d for d in log.decisions if d.t_ns >= full_due_ns]
    assert after[0].first
    assert after[0].t_ns - full_due_ns <= NS_PER_S // 20  # taken the tick the full one is in
    # From when the filter settled (the decision due) the reference is zero: a stop.
    due_ns = back_ns + round(LoopConfig().observer_settle_s * NS_PER_S) + NS_PER_S // 20
    held = [ref for t, ref in log.velocity_references if due_ns <= t < full_due_ns]
    assert len(held) > 40
    assert np.all(np.array(held) == 0.0)
