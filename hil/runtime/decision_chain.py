"""The chain of decisions the guarantee follows, one period to the next.

A decision's budget depends on what came before it: the reference in force (the
last input chosen, from which the next may move one grid step per axis), how many
first decisions are still to take (a start counts ``START_PERIODS`` periods, budget
class START) and when the input in force was chosen (a decision later than tau +
late is a broken premise). The chain also holds the runtime monitor, which judges
every tick against the decision in force: whenever the chain restarts (a stop, a
hold, a late tick, a tube exit) the next decision is a first one from the estimated
velocity, and nothing is judged until it is taken.
"""

from __future__ import annotations

import numpy as np

from hil.controllers.symbolic import DecisionContract
from hil.core.arrays import FloatArray
from hil.core.transient import LATE_S, START_PERIODS
from hil.runtime.monitor import Monitor
from hil.runtime.protocols import SymbolicController
from hil.runtime.resynthesis import VesselState
from hil.runtime.settings import NS_PER_S

__all__ = ["DecisionChain"]


class DecisionChain:
    """The reference in force, the first decisions left, the last choice and the monitor.

    Args:
        monitor: Judges every tick's estimate against the decision in force.
    """

    def __init__(self, monitor: Monitor) -> None:
        self.monitor = monitor
        self.reference: int | None = None
        """Input-grid index of the reference in force; None: the next decision starts
        afresh (start, or after a stop or a hold) from the estimated velocity."""
        self.first_left = START_PERIODS
        """First decisions still to take (budget class START)."""
        self.previous_input = np.zeros(3)
        """The last input chosen (u, v, r), what the cost J compares with."""
        self.chosen_ns: int | None = None
        """When the input in force was chosen (ns); None: no input in force."""

    def restart(self) -> None:
        """Make the next decision a first one; judge nothing until it is taken."""
        self.reference = None
        self.monitor.clear()

    @property
    def first_next(self) -> bool:
        """Whether the next decision is a first one (start, or after a restart)."""
        return self.reference is None or self.first_left > 0

    def vessel_state(self, eta_hat: FloatArray | None) -> VesselState | None:
        """Return the state an early controller must cover: mid-run, the reference in force.

        None when the next decision is a first one: it may take any input into the
        winning set at any value, which only the full solve knows.
        """
        if self.reference is None or self.first_left > 0 or eta_hat is None:
            return None
        return VesselState(eta_hat.copy(), self.reference)

    def held_too_long(self, t_ns: int, period_s: float) -> tuple[float, float] | None:
        """Return (held, allowed) in s when the input in force is held past tau + late.

        The budgets bound an interval of at most tau + :data:`LATE_S`; past that the
        input in force has gone beyond what its decision assumed (a stalled loop).
        """
        if self.chosen_ns is None or self.reference is None:
            return None
        held_s = (t_ns - self.chosen_ns) / NS_PER_S
        allowed_s = period_s + LATE_S
        return (held_s, allowed_s) if held_s > allowed_s else None

    def open(self, controller: SymbolicController, nu_hat: FloatArray) -> tuple[int, bool]:
        """Start a decision: return the reference in force and whether it is a first one.

        A first decision after a restart takes the input nearest the estimated velocity
        `nu_hat` (3,) as its reference, and the start's periods count again.
        """
        self.monitor.clear()
        if self.reference is None:
            self.first_left = START_PERIODS
            return controller.nearest_input(nu_hat), True
        return self.reference, self.first_left > 0

    def close(
        self, t_ns: int, chosen_index: int, chosen: FloatArray, contract: DecisionContract | None
    ) -> None:
        """End a decision: the chosen input (index -1: none, a stop) is now in force.

        A stop (reference zero outside the lattice step) is not budgeted: after it the
        next decision starts afresh from the estimated velocity.
        """
        if chosen_index < 0:
            self.reference = None
            self.chosen_ns = None
            return
        self.previous_input = chosen
        self.reference = chosen_index
        self.chosen_ns = t_ns
        self.first_left = max(self.first_left - 1, 0)
        self.monitor.start(t_ns, contract)

