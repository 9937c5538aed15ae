"""The symbolic decisions of a run: when one is due, the one query, and what it sets.

Every ``decision_period_s`` (and at once after a tube exit, as a first decision) the
decider asks the controller in force one question (:meth:`SymbolicController.decide`:
the cell located once; value, listed inputs, choice and contract back), records the
decision, sets the velocity reference the low level flies and hands the contract to
the runtime monitor. It waits instead when the decision may not be taken: a first
decision under an early controller (it waits for the full solve) or one whose
obstacle report is too old (``obstacles_stale``); both put the reference to zero and
make the next decision a first one. A decision due past tau + late is a broken
premise (``late_interval``) and is taken as a first decision.
"""

from __future__ import annotations

import math

import numpy as np

from hil.controllers.symbolic import Select
from hil.core.arrays import FloatArray
from hil.core.records import Decision, EventLevel
from hil.runtime.controller_slot import ControllerSlot
from hil.runtime.decision_chain import DecisionChain
from hil.runtime.events import EventCode
from hil.runtime.feed import EventSink
from hil.runtime.mode import Mode
from hil.runtime.monitor import Violation
from hil.runtime.progress import Progress, Target
from hil.runtime.protocols import RunLog
from hil.runtime.settings import NS_PER_S, LoopConfig
from hil.runtime.stats import RunStats
from hil.runtime.stopping import Stopping

__all__ = ["Decider"]


class Decider:
    """Takes the run's symbolic decisions and holds the velocity reference they set.

    Args:
        slot: The controller in force and its obstacle report.
        chain: What carries from one decision to the next (reference, monitor).
        selects: The choice among the safe inputs, and among the staying ones where
            docking is not winning.
        log: Every decision is recorded.
        stats: The run's counters.
        event: Records the decider's events.
        stopping: Takes the abort a decision calls for.
        config: The decision period tau and the target's hold time.
        scenario_hash: Identifies the scenario in every decision record.
        wait_for_layout: Obstacles move: a run that loses the winning and the safety
            set waits at rest for a layout that wins instead of aborting
            (:class:`~hil.runtime.progress.Progress`).
    """

    def __init__(
        self,
        slot: ControllerSlot,
        chain: DecisionChain,
        selects: tuple[Select, Select],
        log: RunLog,
        stats: RunStats,
        event: EventSink,
        stopping: Stopping,
        config: LoopConfig,
        scenario_hash: str,
        wait_for_layout: bool = False,
    ) -> None:
        self._slot = slot
        self.chain = chain
        self._select, self._wait_select = selects
        self._log = log
        self._stats = stats
        self._event = event
        self._stopping = stopping
        self._period_s = config.decision_period_s
        self._scenario_hash = scenario_hash
        self.progress = Progress(stats, event, config.dock_hold_s, config.decision_period_s,
                                 wait_for_layout)
        """What the decisions say about the run: target, waits, losses."""
        self.nu_ref = np.zeros(3)
        """The velocity reference in force (u, v, r), shape (3,)."""
        self.next_ns = 0
        """When the next regular decision is due (ns)."""

    def stop_reference(self) -> None:
        """Fly velocity zero; the next decision starts afresh (a first decision)."""
        self.chain.restart()
        self.nu_ref = np.zeros(3)

    def tick(
        self, t_ns: int, eta_hat: FloatArray, nu_hat: FloatArray, settled: bool, mode: Mode
    ) -> Mode:
        """Decide if one is due (or the monitor saw a tube exit); return the loop's mode.

        `settled`: the filter has settled (a first decision waits for it).
        """
        chain = self.chain
        if t_ns >= self.next_ns and (chain.reference is not None or settled):
            self._slot.take_early(t_ns, eta_hat, chain.reference if chain.first_left == 0 else None)
            self._check_late(t_ns)
            # A stale obstacle report leaves the decision due: taken once a fresher one is in.
            if not self._ready(t_ns):
                return mode
            for violation in chain.monitor.at_decision(t_ns, eta_hat):
                self._violation(t_ns, violation)
            return self._decide(t_ns, eta_hat, nu_hat, mode)
        exit_ = chain.monitor.tick(t_ns, eta_hat)
        if exit_ is None:
            return mode
        # The guarantee no longer covers this interval: decide afresh, as a first decision
        # from the estimated velocity, now.
        self._violation(t_ns, exit_)
        chain.reference = None
        if not self._ready(t_ns):
            self.next_ns = t_ns  # decide once a fresher report is in
            return mode
        return self._decide(t_ns, eta_hat, nu_hat, mode)

    def _violation(self, t_ns: int, v: Violation) -> None:
        """Count and record one broken promise of a decision (runtime monitor)."""
        self._stats.count_violation(v.code, v.size)
        self._event(t_ns, v.level, v.code, v.text)

    def _ready(self, t_ns: int) -> bool:
        """Return whether a decision may be taken now; else the reference goes to zero.

        A first decision under an early controller waits for the full solve (it may take
        any input into the winning set, at any value); a decision whose obstacle report
        is too old (:meth:`ControllerSlot.fresh`) waits for a fresher one, and is then a
        first decision.
        """
        if (self._slot.in_force_early and self.chain.first_next) or not self._slot.fresh(t_ns):
            self.stop_reference()
            return False
        return True

    def _check_late(self, t_ns: int) -> None:
        """Name a decision due later than tau + late: it is then a first decision.

        The interval's successor is not judged (its premise broke; the event says so,
        with its size).
        """
        late = self.chain.held_too_long(t_ns, self._period_s)
        if late is None:
            return
        held_s, allowed_s = late
        self._stats.late_intervals += 1
        self._stats.worst_late_s = max(self._stats.worst_late_s, held_s - allowed_s)
        self._event(
            t_ns, EventLevel.ERROR, EventCode.LATE_INTERVAL,
            f"the input chosen at t={self.chain.chosen_ns} ns was held {held_s:.3f} s, past "
            f"tau + late = {allowed_s:g} s by {held_s - allowed_s:.3f} s (the loop stalled): "
            "no budget covers it; deciding at once as a first decision",
        )  # fmt: skip
        self.chain.restart()

    def _decide(self, t_ns: int, eta_hat: FloatArray, nu_hat: FloatArray, mode: Mode) -> Mode:
        """Take one decision now and schedule the next; return the loop's mode after it."""
        self.next_ns = t_ns + round(self._period_s * NS_PER_S)
        controller = self._slot.controller
        if controller is None:
            self.chain.restart()
            if mode is not Mode.WAITING:
                self.nu_ref = np.zeros(3)
                self._event(t_ns, EventLevel.ERROR, EventCode.NO_CONTROLLER,
                            "no valid controller; velocity reference zero")
            return mode
        reference, first = self.chain.open(controller, nu_hat)
        answer = controller.decide(
            eta_hat, reference, first, self.chain.previous_input, self._select, self._wait_select
        )
        target = self.progress.judge(
            t_ns, answer, eta_hat, self._slot.version, mode is Mode.AT_TARGET
        )
        if self.progress.abort is not None:
            self._stopping.abort = self.progress.abort
        if target is not Target.OUTSIDE:
            mode = Mode.DOCKED if target is Target.DOCKED else Mode.AT_TARGET
        elif mode is Mode.AT_TARGET:
            mode = Mode.RUNNING  # pushed out of the target: steer back in
        chosen_index = answer.chosen
        chosen = controller.inputs[chosen_index].copy() if chosen_index >= 0 else np.zeros(3)
        self.nu_ref = chosen.copy()
        self.chain.close(t_ns, chosen_index, chosen, answer.contract)
        self._stats.decisions += 1
        layout = self._slot.layout
        self._log.decision(Decision.from_arrays(
            t_ns, eta_hat, answer.cell, answer.value, math.isfinite(answer.value),
            controller.inputs[answer.inputs], answer.inputs, chosen_index,
            self._slot.version, self._scenario_hash, chosen_input=chosen,
            reference_index=reference, first=first, report_age_s=self._slot.age_s,
            report_t_ns=-1 if layout is None else layout.t_ns,
        ))  # fmt: skip
        return mode
