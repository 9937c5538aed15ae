"""What each decision says about the run: the target reached and held, a wait, a loss.

A decision of value 0 is in the target: the vessel holds position there and has
docked after ``dock_hold_s``. A decision on the safety controller (docking not
winning, the vessel able to stay safe) starts or continues a wait. A decision outside
the winning and the safety set stops the vessel for a period and, at the run's first
decision or a second time in a row, aborts the run; where obstacles move (a later
layout may open a way again) it stops the vessel instead and waits at rest, deciding
every period afresh, until a layout wins again or the run's time limit.
"""

from __future__ import annotations

import enum
import math

import numpy as np

from hil.controllers.symbolic import Answer
from hil.core.arrays import FloatArray
from hil.core.records import EventLevel
from hil.runtime.events import EventCode
from hil.runtime.feed import EventSink
from hil.runtime.settings import NS_PER_S
from hil.runtime.stats import RunStats

__all__ = ["Progress", "Target", "not_winning_abort"]


class Target(enum.Enum):
    """Where a decision leaves the vessel with respect to the target."""

    OUTSIDE = "outside"
    """Not in the target (value > 0, or nothing safe)."""
    HOLDING = "holding"
    """In the target, holding position."""
    DOCKED = "docked"
    """In the target for ``dock_hold_s``: the run is over."""


class Progress:
    """Judges each decision's answer for the run; counts and says what changed.

    Args:
        stats: The run's counters.
        event: Records the events.
        dock_hold_s: How long the target must be held to dock (s).
        period_s: The decision period (s).
        wait_for_layout: Obstacles move: a decision outside the winning and the safety
            set after the first stops the vessel (velocity zero under the low level,
            held at rest) and the run waits for a layout that wins instead of aborting.
    """

    def __init__(
        self, stats: RunStats, event: EventSink, dock_hold_s: float, period_s: float,
        wait_for_layout: bool = False,
    ) -> None:
        self._stats = stats
        self._event = event
        self._dock_hold_ns = dock_hold_s * NS_PER_S
        self._dock_hold_s = dock_hold_s
        self._period_s = period_s
        self._wait_for_layout = wait_for_layout
        self.start_ns = 0
        """The run's start (ns), for the time to the target."""
        self.abort: str | None = None
        """Why the last decision ends the run (None: it does not)."""
        self._target_since_ns = 0
        self._staying = False
        self._not_winning_before = False

    def judge(
        self, t_ns: int, answer: Answer, eta_hat: FloatArray, version: int, holding: bool
    ) -> Target:
        """Judge one decision's answer at the estimated pose `eta_hat` (3,).

        Args:
            t_ns: The decision's time (ns).
            answer: The controller's answer.
            eta_hat: The estimated pose.
            version: The controller version that answered.
            holding: The vessel was holding the target before this decision.
        """
        self.abort = None
        self._note_staying(t_ns, answer.staying, eta_hat, version)
        target = Target.OUTSIDE
        if answer.value == 0.0:
            target = self._at_target(t_ns, holding)
        elif answer.staying:
            self._stats.staying_decisions += 1
        elif math.isinf(answer.value):
            self._not_winning(t_ns, eta_hat, answer.cell)
        lost = math.isinf(answer.value) and not answer.staying
        if self._wait_for_layout and self._not_winning_before and math.isfinite(answer.value):
            self._event(t_ns, EventLevel.INFO, EventCode.DOCKING_BACK,
                        f"a layout wins again from {np.round(eta_hat, 3).tolist()}: docking on")
        self._not_winning_before = lost
        return target

    def _not_winning(self, t_ns: int, eta_hat: FloatArray, cell: int) -> None:
        """A decision outside the winning and the safety set: stop, and abort if lost.

        Where obstacles move, a run past its first decision waits at rest instead
        (said once per wait).
        """
        s = self._stats
        s.not_winning_decisions += 1
        waits = self._wait_for_layout and s.decisions > 0
        if waits and self._not_winning_before:
            return  # the wait goes on; said when it began
        state = np.round(eta_hat, 3).tolist()
        then = ", and waiting at rest for a layout that wins (obstacles move)" if waits else ""
        self._event(t_ns, EventLevel.ERROR, EventCode.NOT_WINNING,
                    f"state {state} outside the winning and the safety set; stopping{then}")
        if waits:
            s.layout_waits += 1
            return
        self.abort = not_winning_abort(
            state, cell < 0, s.decisions == 0, self._not_winning_before, self._period_s
        )

    def _note_staying(self, t_ns: int, staying: bool, eta_hat: FloatArray, version: int) -> None:
        """Say when the vessel starts waiting on the safety controller, and when it docks on."""
        if staying == self._staying:
            return
        self._staying = staying
        state = np.round(eta_hat, 3).tolist()
        if staying:
            self._stats.docking_lost += 1
            self._event(
                t_ns, EventLevel.WARN, EventCode.DOCKING_LOST,
                f"docking is not winning from {state} (controller v{version}): "
                "staying in the safety set, slowing, until it wins again",
            )  # fmt: skip
        else:
            self._event(t_ns, EventLevel.INFO, EventCode.DOCKING_BACK,
                        f"docking is winning again from {state}: docking on")

    def _at_target(self, t_ns: int, holding: bool) -> Target:
        s = self._stats
        if s.target_reached_ns is None:
            s.target_reached_ns = t_ns
            self._event(t_ns, EventLevel.INFO, EventCode.TARGET_REACHED,
                        f"target reached after {(t_ns - self.start_ns) / NS_PER_S:.1f} s")
        if not holding:
            self._target_since_ns = t_ns
            return Target.HOLDING
        if t_ns - self._target_since_ns < self._dock_hold_ns:
            return Target.HOLDING
        s.docked_ns = t_ns
        s.end_reason = "docked"
        self._event(t_ns, EventLevel.INFO, EventCode.DOCKED,
                    f"held the target for {self._dock_hold_s:.0f} s")
        return Target.DOCKED


def not_winning_abort(
    state: list[float], outside_grid: bool, first_decision: bool, again: bool, period_s: float
) -> str | None:
    """Return why a run aborts on a decision outside the winning and the safety set.

    Args:
        state: The estimated pose, rounded for the text.
        outside_grid: The state is not on the grid at all.
        first_decision: It is the run's first decision: the start is lost.
        again: The decision before was not winning either (stopped for a period).
        period_s: The decision period (s).

    Returns:
        The reason, or None: the vessel is stopped for one period and decides again.
    """
    where = "outside the grid" if outside_grid else "outside the winning set"
    if first_decision:
        return (
            f"start {state} is {where}: no input is safe from there "
            "(too close to an obstacle or a wall, cut off from the target, "
            "or moving too fast to turn away in time)"
        )
    if again:
        return f"state {state} still {where} after {period_s:g} s stopped: no safe input"
    return None
