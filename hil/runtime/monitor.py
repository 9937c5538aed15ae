"""The runtime monitor: the estimated pose held to the current decision's contract.

Every decision that chose an input promises, through its
:class:`~hil.controllers.symbolic.DecisionContract` (the one judge the campaign
and the replay use too), that over [0, tau + late] the true centre stays in the
swept tube's cells, and that at the next decision the estimated state is in the
successor cells with a value strictly below the decision's. The tables are padded
for the estimation error, so the estimate may lie up to the budget's
``estimation_position_m`` outside the tube cells and still be consistent with the
promise; farther is a violation. The successor box bounds the next *estimated*
cell, so it is judged without tolerance.

:class:`Monitor` keeps the contract of the decision in force (built once per
decision) and answers, per tick, with at most one :class:`Violation`:

- :meth:`Monitor.tick`: the estimate farther than ``estimation_position_m`` from
  the tube cells (``TUBE_EXIT``, metres); the loop reacts with a first decision;
- :meth:`Monitor.at_decision`: the estimate at the next regular decision outside
  the successor cells (``SUCCESSOR_MISS``, metres and radians) or its value not
  below the decision's (``VALUE_NOT_DECREASING``, steps).

Each judge is numpy on one pose (tens of microseconds), so it does not slow the
20-Hz loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hil.controllers.symbolic import DecisionContract
from hil.core.arrays import FloatArray
from hil.core.records import EventLevel
from hil.core.transient import BudgetClass
from hil.runtime.events import EventCode
from hil.runtime.settings import NS_PER_S

__all__ = ["Monitor", "Violation"]


@dataclass(frozen=True, slots=True)
class Violation:
    """One broken promise of a decision, as the loop records it.

    Attributes:
        code: TUBE_EXIT, SUCCESSOR_MISS or VALUE_NOT_DECREASING.
        level: Severity of its event.
        size: How far: metres (tube, successor position), radians (successor
            heading, in `heading_rad`) or value steps (descent).
        decided_ns: Time of the decision whose contract was broken (ns).
        text: The event's text: what, how far, which decision.
        heading_rad: Angle to the successor headings (rad); 0 unless a successor miss.
    """

    code: EventCode
    level: EventLevel
    size: float
    decided_ns: int
    text: str
    heading_rad: float = 0.0


def _t(t_ns: int) -> str:
    return f"t={t_ns / NS_PER_S:.3f} s"


class Monitor:
    """Holds the decision in force to its contract, one estimated pose at a time.

    Args:
        estimation_position_m: The budget's bound on the estimate's position error
            (m): the tolerance of the tube judge.
        tick_s: Loop period (s): a decision counts as the regular next one from
            tau - tick / 2 after the previous on.
    """

    def __init__(self, estimation_position_m: float = 0.0, tick_s: float = 0.05) -> None:
        if not (math.isfinite(estimation_position_m) and estimation_position_m >= 0.0):
            raise ValueError(
                f"estimation_position_m must be finite and >= 0, got {estimation_position_m!r}"
            )
        self.estimation_position_m = float(estimation_position_m)
        self._half_tick_ns = round(tick_s * NS_PER_S / 2)
        self._contract: DecisionContract | None = None
        self._decided_ns = 0

    @property
    def contract(self) -> DecisionContract | None:
        """The contract of the decision in force; None when none is judged."""
        return self._contract

    def start(self, t_ns: int, contract: DecisionContract | None) -> None:
        """Hold the decision taken at `t_ns` to `contract` from now on (None: judge nothing)."""
        self._contract = contract
        self._decided_ns = t_ns

    def clear(self) -> None:
        """Judge nothing until the next decision (a stop, a hold, a new controller)."""
        self._contract = None

    def tick(self, t_ns: int, eta_hat: FloatArray) -> Violation | None:
        """Judge the estimate against the tube of the decision in force.

        Past tau + late the tube promises nothing more and is no longer judged.

        Returns:
            A TUBE_EXIT violation when the estimate is farther than the estimation
            bound from the tube cells, else None.
        """
        c = self._contract
        if c is None:
            return None
        elapsed_s = (t_ns - self._decided_ns) / NS_PER_S
        if elapsed_s > c.tau_s + c.late_s:
            return None
        d = float(c.tube_distance_m(np.asarray(eta_hat, dtype=np.float64)[None, :])[0])
        if d <= self.estimation_position_m:
            return None
        return Violation(
            EventCode.TUBE_EXIT,
            EventLevel.ERROR,
            d,
            self._decided_ns,
            f"estimate {d:.4f} m from the tube cells of the decision at {_t(self._decided_ns)} "
            f"({elapsed_s:.2f} s in; estimation bound {self.estimation_position_m:.4f} m); "
            "re-deciding as a first decision",
        )

    def at_decision(self, t_ns: int, eta_hat: FloatArray) -> list[Violation]:
        """Judge the estimate at a new decision against the previous decision's end.

        Only a regular next decision (tau - half a tick after the previous, or later,
        within tau + late) is judged: a re-decision cuts the interval short.

        Returns:
            SUCCESSOR_MISS and/or VALUE_NOT_DECREASING violations (maybe none).
        """
        c = self._contract
        if c is None:
            return []
        elapsed_ns = t_ns - self._decided_ns
        tau_ns = round(c.tau_s * NS_PER_S)
        if elapsed_ns < tau_ns - self._half_tick_ns:
            return []
        if elapsed_ns > round((c.tau_s + c.late_s) * NS_PER_S) + self._half_tick_ns:
            return []  # held past what the tables cover: a premise broken, not a promise
        pose = np.asarray(eta_hat, dtype=np.float64)[None, :]
        out: list[Violation] = []
        if not bool(c.in_successor(pose)[0]):
            d = float(c.successor_distance_m(pose)[0])
            h = float(c.heading_distance_rad(pose)[0])
            out.append(
                Violation(
                    EventCode.SUCCESSOR_MISS,
                    EventLevel.WARN,
                    d,
                    self._decided_ns,
                    f"estimate {d:.4f} m and {h:.4f} rad outside the successor cells of the "
                    f"decision at {_t(self._decided_ns)}",
                    heading_rad=h,
                )
            )
        value = int(c.end_values(pose)[0])
        if not (0 <= value < c.value):
            shown = "losing" if value < 0 else str(value)
            if c.staying:
                shown, was = "outside the safety set", "a staying decision's (in it)"
            elif c.budget_class == BudgetClass.START:
                was = "a first decision's (any winning value)"
            else:
                was = str(c.value)
            out.append(
                Violation(
                    EventCode.VALUE_NOT_DECREASING,
                    EventLevel.WARN,
                    float(value - c.value) if value >= 0 else math.inf,
                    self._decided_ns,
                    f"value {shown} at the next decision not below {was} of the decision at "
                    f"{_t(self._decided_ns)}",
                )
            )
        return out
