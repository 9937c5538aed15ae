"""The runtime waits on the safety controller where docking is lost, and docks on after.

A scripted controller answers decisions 0-1 for docking, 2-4 with staying inputs only
(docking not winning, the vessel can stay safe), then for docking again: the loop must
hand the decision its waiting choice (the slowest by default) for the staying inputs,
say when docking was lost and when it is back, and not stop the vessel.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.adapters.sim import ObstacleMotion, SimConfig, SimWorld
from hil.controllers.symbolic import Answer, Options, Select, wait_slowest
from hil.core.records import ControllerSource
from hil.core.samples import ObstacleLayout
from hil.core.shapes import Rect
from hil.runtime.assembly import low_level_for
from hil.runtime.events import EventCode
from hil.runtime.loop import Runtime, World
from hil.runtime.report_age import ReportAgeBudget
from hil.runtime.resynthesis import ResynthesisMode, Resynthesizer
from hil.runtime.settings import LoopConfig
from hil.runtime.stats import RunStats
from hil.runtime.trace import MemoryLog
from tests.runtime.test_low_level_pin import START, TrueVelocity

F = NDArray[np.float64]

INPUTS = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.05, 0.05, 0.0], [0.1, 0.0, 0.1]])
STAYING = (2, 4)  # decisions [2, 4) wait


class WaitingController:
    """Docking, then a wait (staying inputs 1 and 2 only), then docking again."""

    def __init__(self) -> None:
        self.decisions = 0
        self.contracts: list[bool] = []
        self.source = ControllerSource.SOLVED

    @property
    def inputs(self) -> F:
        return INPUTS

    def locate(self, state: F) -> int:
        return 0

    def nearest_input(self, velocity: F) -> int:
        return 0

    def value(self, state: F, reference: int, first: bool) -> float:
        return 3.0

    def safe_input_indices(self, state: F, reference: int, first: bool) -> NDArray[np.int64]:
        return np.array([3], dtype=np.int64)

    def decide(
        self,
        state: F,
        reference: int,
        first: bool,
        previous: F,
        select: Select,
        wait_select: Select,
    ) -> Answer:
        n = self.decisions
        self.decisions += 1
        staying = STAYING[0] <= n < STAYING[1]
        indices = np.array([1, 2] if staying else [3], dtype=np.int64)
        pick = wait_select if staying else select
        options = Options(INPUTS[indices], indices, np.full(indices.size, -1), previous, state)
        self.contracts.append(staying)
        value = math.inf if staying else 3.0
        return Answer(0, value, indices, staying, int(indices[pick(options)]), None)


def _run(config: SimConfig, controller: WaitingController, n_decisions: int,
         report_ages: ReportAgeBudget | None) -> tuple[RunStats, MemoryLog]:
    """Run the loop on `config`'s world for `n_decisions` decisions under `controller`."""
    world = SimWorld(config, max_duration_s=2.0 * n_decisions + 5.0)

    def solve(layout: ObstacleLayout, report_age_s: float) -> WaitingController:
        return controller

    loop = LoopConfig(
        resynthesis_period_s=None, max_duration_s=2.0 * n_decisions - 0.025,
        observer_settle_s=0.0,
    )  # fmt: skip
    log = MemoryLog()
    runtime = Runtime(
        World(world.clock, world.pose, world.imu, world.obstacles, world.thrusters),
        TrueVelocity(world), low_level_for(loop.loop_hz),
        Resynthesizer(solve, ResynthesisMode.INLINE), lambda options: 0, log, loop,
        report_ages=report_ages,
    )  # fmt: skip
    return runtime.run(), log


def test_a_lost_docking_is_waited_out_on_the_staying_inputs() -> None:
    n_decisions = 6
    controller = WaitingController()
    stats, log = _run(SimConfig(start=START, seed=3), controller, n_decisions, None)

    assert stats.decisions == n_decisions
    assert stats.staying_decisions == STAYING[1] - STAYING[0]
    assert stats.docking_lost == 1
    assert stats.not_winning_decisions == 0
    assert not stats.aborted
    codes = log.event_codes()
    assert codes.count(EventCode.DOCKING_LOST.value) == 1
    assert codes.count(EventCode.DOCKING_BACK.value) == 1
    assert codes.index(EventCode.DOCKING_LOST.value) < codes.index(EventCode.DOCKING_BACK.value)
    chosen = [d.chosen_index for d in log.decisions]
    staying = np.array([1, 2])
    waiting = int(staying[wait_slowest(Options(INPUTS[staying], staying, -np.ones(2, int),
                                               np.zeros(3), np.zeros(3)))])
    assert waiting == 1  # the slower of the two by J against rest: the runtime's default
    assert chosen == [3, 3, waiting, waiting, 3, 3]
    assert [d.staying for d in log.decisions] == [False, False, True, True, False, False]
    assert controller.contracts == [False, False, True, True, False, False]


LOST = (2, 5)
"""Decisions [2, 5) are outside the winning and the safety set (a closed passage)."""


class ClosingController(WaitingController):
    """Docking, then nothing safe for three decisions (no input listed), then docking."""

    def __init__(self) -> None:
        super().__init__()
        self.asked = 0

    def decide(self, *args: object) -> Answer:
        n = self.asked
        self.asked += 1
        if LOST[0] <= n < LOST[1]:
            return Answer(0, math.inf, np.zeros(0, dtype=np.int64), False, -1, None)
        return Answer(0, 3.0, np.array([3], dtype=np.int64), False, 3, None)


@pytest.mark.parametrize("moving", [True, False])
def test_a_closed_passage_is_waited_out_at_rest_only_where_obstacles_move(moving: bool) -> None:
    """Obstacles that move may open the way again: the vessel stops and waits, deciding
    afresh every period, and docks on; fixed ones cannot, so the second loss aborts."""
    n_decisions = 7
    # A far obstacle reported every second (a zero motion): reports stay fresh.
    far = Rect(-3.0, -2.5, 2.0, 2.5)
    config = SimConfig(start=START, seed=3, obstacles=(far,),
                       motions=(ObstacleMotion(0, (0.0, 0.0), 0.0, 100.0),))
    stats, log = _run(config, ClosingController(), n_decisions,
                      ReportAgeBudget(1.0, tracks=moving))

    codes = log.event_codes()
    if not moving:
        assert stats.aborted
        assert "still outside the winning set" in stats.end_reason
        assert stats.decisions == LOST[0] + 2
        assert stats.layout_waits == 0
        return
    assert not stats.aborted
    assert stats.decisions == n_decisions
    assert stats.not_winning_decisions == LOST[1] - LOST[0]
    assert stats.layout_waits == 1
    assert codes.count(EventCode.NOT_WINNING.value) == 1  # said once per wait
    assert codes.count(EventCode.DOCKING_BACK.value) == 1
    decisions = log.decisions
    assert [d.chosen_index for d in decisions] == [3, 3, -1, -1, -1, 3, 3]
    # Every decision after a stop is a first one, from the estimated velocity.
    assert [d.first for d in decisions[LOST[0] + 1:]] == [True] * (n_decisions - LOST[0] - 1)
    # The vessel was brought to rest while waiting: velocity zero flown under the low level.
    t_back = decisions[LOST[1]].t_ns
    refs = [r for t, r in log.velocity_references if decisions[LOST[0]].t_ns <= t < t_back]
    assert refs
    assert all(np.all(r == 0.0) for r in refs)
