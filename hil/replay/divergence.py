"""A re-run's decisions against the recorded ones, and the divergences both ways allow.

The stack re-run and the re-simulation take their own decisions, compared with the
recorded ones by :func:`compare_rerun_decisions`: one taken the other way is accepted
when :func:`explain_divergence` finds both ways legitimate (the two states within
``BOUNDARY_TOLERANCE`` of each other and the recorded decision the current code's across
a cell boundary within it, or a cost tie); it is reported (``boundary_decisions`` or
``cost_ties``, ``divergence``) and the re-run is compared with the recording only up to it,
since everything after it legitimately departs. Any other difference is a regression.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hil.bag.run_data import RunData
from hil.core.arrays import FloatArray
from hil.core.geometry import wrap_angles
from hil.core.records import Decision
from hil.replay.controllers import ControllerCache
from hil.replay.decisions import (
    BOUNDARY_TOLERANCE,
    COST_TOLERANCE,
    across_boundaries,
    decision_controllers,
    is_cost_tie,
    mismatch,
    recompute,
)
from hil.replay.regression import Finding, time_s
from hil.runtime.protocols import SymbolicController

__all__ = [
    "BOUNDARY",
    "TIE",
    "Divergence",
    "compare_rerun_decisions",
    "explain_divergence",
]


BOUNDARY = "cell boundary"
"""Kind of an accepted divergence: the re-run's state within BOUNDARY_TOLERANCE of a cell
boundary, the recorded decision the current code's on the other side."""
TIE = "cost tie"
"""Kind of an accepted divergence: the same cell and safe set, the two chosen inputs of equal
cost J within COST_TOLERANCE."""


@dataclass(frozen=True, slots=True)
class Divergence:
    """A re-run decision taken the other way than recorded, where both ways are legitimate.

    A re-run (stack or re-simulation) on another machine may round the state to the other
    side of a cell boundary, or break a cost tie the other way: its decision then differs
    from the recorded one and everything after it legitimately departs from the recording,
    so the re-run is compared with the recording only up to this decision.

    Attributes:
        kind: :data:`BOUNDARY` or :data:`TIE`.
        recorded: The recorded decision.
        replayed: The re-run's decision at the same time.
    """

    kind: str
    recorded: Decision
    replayed: Decision

    @property
    def t_ns(self) -> int:
        """Time of the decision (ns): the re-run is compared with the recording before it."""
        return self.recorded.t_ns

    @property
    def tolerance(self) -> float:
        """The tolerance within which both ways hold (m and rad, or relative cost)."""
        return BOUNDARY_TOLERANCE if self.kind == BOUNDARY else COST_TOLERANCE

    def describe(self) -> str:
        """Return one line: what was taken each way, why both hold, where comparison ended."""
        why = (
            f"its state lies within {BOUNDARY_TOLERANCE:g} (m, rad) of a cell boundary and the "
            "recorded decision is the current code's on the other side"
            if self.kind == BOUNDARY
            else f"both chosen inputs cost the same J within {COST_TOLERANCE:g} (relative)"
        )
        r, n = self.recorded, self.replayed
        return (
            f"decision taken the other way ({self.kind}, accepted): recorded chosen "
            f"{r.chosen_index} value {r.value} cell {r.cell}, re-run chosen {n.chosen_index} "
            f"value {n.value} cell {n.cell}; {why}, so both are legitimate and the runs "
            f"diverge from here: not compared after {time_s(self.t_ns)}"
        )

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary (states in m, m, rad)."""

        def side(d: Decision) -> dict[str, Any]:
            return {
                "state": list(d.state),
                "cell": d.cell,
                "value": d.value,
                "chosen": d.chosen_index,
                "chosen_input": list(d.chosen_input),
            }

        return {
            "t_ns": self.t_ns,
            "kind": self.kind,
            "tolerance": self.tolerance,
            "recorded": side(self.recorded),
            "replayed": side(self.replayed),
        }


def _same_decision(a: Decision, b: Decision) -> bool:
    return (a.chosen_index, a.value, a.cell) == (b.chosen_index, b.value, b.cell)


def explain_divergence(
    recorded: Decision, replayed: Decision, controller: SymbolicController, previous: FloatArray
) -> str | None:
    """Return why a re-run decision that differs from the recorded one is legitimate, or None.

    Both states must agree within BOUNDARY_TOLERANCE per axis (m, m, rad; heading
    wrapped): a re-run departs from the recording by its rounding only (1.5e-10 m measured
    between two CPUs over a whole re-simulation), so states farther apart are a change,
    not noise. Then the divergence is

    - :data:`TIE` when both decisions have the same cell, value and safe set and the two
      chosen inputs cost the same J given `previous` (3,) within COST_TOLERANCE;
    - :data:`BOUNDARY` when a state within BOUNDARY_TOLERANCE of the re-run's, across a
      cell boundary, gives the recorded decision with the current code (the check the
      ``decisions`` check makes at the recorded state).

    Anything else is None: a regression.

    Args:
        recorded: The recorded decision.
        replayed: The re-run's decision at the same time.
        controller: The current code's controller for the recorded layout.
        previous: The previous choice (u m/s, v m/s, r rad/s) the cost J is taken against.
    """
    rec_state, new_state = np.array(recorded.state), np.array(replayed.state)
    apart = new_state - rec_state
    apart[2] = float(wrap_angles(apart[2]))
    if not np.all(np.abs(apart) <= BOUNDARY_TOLERANCE):
        return None
    same_safe = sorted(recorded.safe_input_indices) == sorted(replayed.safe_input_indices)
    if (
        (recorded.cell, recorded.value) == (replayed.cell, replayed.value)
        and same_safe
        and recorded.chosen_index in replayed.safe_input_indices
        and is_cost_tie(controller, recorded.chosen_index, replayed.chosen_index, previous)
    ):
        return TIE
    for state in across_boundaries(controller, new_state, replayed.cell):
        got = recompute(controller, state, previous, recorded.reference_index, recorded.first)
        if mismatch(recorded, got, controller, previous)[0] is None:
            return BOUNDARY
    return None


def compare_rerun_decisions(
    run: RunData, replayed: Sequence[Decision], controllers: ControllerCache
) -> tuple[list[Finding], Divergence | None]:
    """Compare a re-run's decisions with the recorded ones, matched by time.

    A re-run decision that differs from the recorded one is a finding unless
    :func:`explain_divergence` accepts it: then it is returned as the divergence and no
    later decision is compared (the runs legitimately part there); decisions recorded or
    re-run only before it are findings.

    Returns:
        The findings in time order and the accepted divergence (None without one).
    """
    by_t = {d.t_ns: d for d in replayed}
    findings: list[Finding] = []
    divergence: Divergence | None = None
    previous = np.zeros(3)
    for d, controller in decision_controllers(run, controllers):
        other = by_t.pop(d.t_ns, None)
        if other is None:
            findings.append(Finding("decision: recorded but not taken in the re-run", d.t_ns))
        elif not _same_decision(d, other):
            kind = (
                None
                if isinstance(controller, str)
                else explain_divergence(d, other, controller, previous)
            )
            if kind is not None:
                divergence = Divergence(kind, d, other)
                break
            findings.append(
                Finding(
                    f"decision: recorded chosen {d.chosen_index} value {d.value} cell {d.cell}, "
                    f"re-run chosen {other.chosen_index} value {other.value} cell {other.cell} "
                    f"at state {[round(v, 4) for v in other.state]} (not within "
                    f"{BOUNDARY_TOLERANCE:g} of a cell boundary nor a cost tie)",
                    d.t_ns,
                    {"recorded_state": list(d.state), "replayed_state": list(other.state)},
                )
            )
        if d.chosen_index >= 0:
            previous = np.array(d.chosen_input)
    end = divergence.t_ns if divergence is not None else None
    findings.extend(
        Finding("decision: taken in the re-run, not recorded", t)
        for t in sorted(by_t)
        if end is None or t < end
    )
    findings.sort(key=lambda f: f.t_ns if f.t_ns is not None else -1)
    return findings, divergence
