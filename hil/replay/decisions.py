"""The decisions check: every recorded decision taken again with the current code.

At every recorded decision, the controller for the recorded obstacle layout is
synthesized anew (one per distinct layout, cached) and queried at the recorded
estimated state: cell, winning status, value, safe-input set and the input the
paper's J picks given the previous recorded choice. Any difference is a regression.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hil.bag.run_data import RunData
from hil.controllers.symbolic import NoWinningSetError
from hil.core.records import Decision
from hil.core.samples import ObstacleLayout
from hil.replay.controllers import ControllerCache
from hil.replay.regression import Check, Finding, Status, time_s
from hil.runtime.assembly import SymbolicAdapter, select_index
from hil.runtime.stack import SymbolicController

FloatArray = NDArray[np.float64]
_READY = re.compile(r"controller v(\d+)\b")


@dataclass(frozen=True, slots=True)
class Recomputed:
    """A decision recomputed with the current code at a recorded state.

    Attributes:
        cell: Flat cell index (-1 outside the grid).
        value: Value at the state (+inf outside the winning set).
        safe: Input-grid indices of the safe inputs, sorted.
        chosen: Input-grid index of the chosen input, -1 for none.
    """

    cell: int
    value: float
    safe: tuple[int, ...]
    chosen: int

    @property
    def winning(self) -> bool:
        """Whether the state is in the winning set."""
        return math.isfinite(self.value)


def recompute(
    controller: SymbolicController, state: FloatArray, previous: FloatArray
) -> Recomputed:
    """Take the runtime's decision at `state` (3,) given the previous choice (3,).

    Mirrors :meth:`hil.runtime.loop.Runtime._decide`: no input in the target
    (value 0) or outside the winning set (value inf).
    """
    cell = controller.locate(state)
    value = controller.value(state)
    if value == 0.0 or math.isinf(value):
        return Recomputed(cell, value, (), -1)
    indices = controller.safe_input_indices(state)
    chosen = -1
    if indices.size:
        chosen = int(indices[select_index(controller.inputs[indices], previous)])
    return Recomputed(cell, value, tuple(sorted(int(i) for i in indices)), chosen)


def _version_times(run: RunData) -> dict[int, int]:
    """Return when each controller version was swapped in (ns), from the events."""
    out: dict[int, int] = {}
    for event in run.events:
        match = _READY.match(event.text) if event.code == "controller_ready" else None
        if match:
            out.setdefault(int(match.group(1)), event.t_ns)
    return out


def layout_at(run: RunData, t_ns: int) -> ObstacleLayout | None:
    """Return the newest recorded layout stamped at or before `t_ns`."""
    best: ObstacleLayout | None = None
    for layout in run.layouts:
        if layout.t_ns <= t_ns and (best is None or layout.t_ns >= best.t_ns):
            best = layout.as_obstacle_layout()
    return best


def _inputs(controller: SymbolicController, indices: tuple[int, ...]) -> list[list[float]]:
    return [[round(float(v), 6) for v in controller.inputs[i]] for i in indices]


def _mismatch(d: Decision, got: Recomputed, controller: SymbolicController) -> Finding | None:
    recorded_safe = tuple(sorted(d.safe_input_indices))
    fields = [
        name
        for name, same in (
            ("cell", d.cell == got.cell),
            ("winning", d.winning == got.winning),
            ("value", d.value == got.value),
            ("safe set", recorded_safe == got.safe),
            ("chosen input", d.chosen_index == got.chosen),
        )
        if not same
    ]
    if not fields:
        return None
    only_rec = sorted(set(recorded_safe) - set(got.safe))
    only_new = sorted(set(got.safe) - set(recorded_safe))
    state = [round(v, 4) for v in d.state]
    message = (
        f"{', '.join(fields)} differ at state {state}: recorded chosen {d.chosen_index} "
        f"{list(d.chosen_input)} value {d.value}, replayed chosen {got.chosen}"
        f"{_inputs(controller, (got.chosen,)) if got.chosen >= 0 else ''} value {got.value}; "
        f"safe set recorded {len(recorded_safe)}, replayed {len(got.safe)} "
        f"(only recorded {only_rec[:8]}, only replayed {only_new[:8]})"
    )
    return Finding(
        message,
        d.t_ns,
        {
            "fields": fields,
            "state": list(d.state),
            "recorded": {
                "cell": d.cell,
                "value": d.value,
                "winning": d.winning,
                "safe": list(recorded_safe),
                "chosen": d.chosen_index,
                "chosen_input": list(d.chosen_input),
            },
            "replayed": {
                "cell": got.cell,
                "value": got.value,
                "winning": got.winning,
                "safe": list(got.safe),
                "chosen": got.chosen,
                "safe_inputs": _inputs(controller, got.safe),
            },
        },
    )


def _recomputed(
    run: RunData, controllers: ControllerCache
) -> Iterator[tuple[Decision, Recomputed | str, SymbolicAdapter | None]]:
    """Yield each recorded decision with its recomputation (or why there is none)."""
    ready = _version_times(run)
    previous = np.zeros(3)
    for d in run.decisions:
        layout = layout_at(run, ready.get(d.controller_version, d.t_ns))
        if layout is None:
            yield d, "no obstacle layout recorded before this decision", None
            continue
        try:
            controller = controllers(layout)
        except NoWinningSetError as err:
            yield d, f"recorded a decision, but now: {err}", None
            continue
        yield d, recompute(controller, np.array(d.state), previous), controller
        if d.chosen_index >= 0:
            previous = np.array(d.chosen_input)


def replayed_decisions(run: RunData, controllers: ControllerCache) -> list[Decision]:
    """Return the decisions the current code takes at the recorded states, in order.

    A decision that cannot be recomputed (no layout, no winning set) comes back
    with no safe input and no choice, so it shows as different.
    """
    out = []
    for d, got, controller in _recomputed(run, controllers):
        if isinstance(got, str) or controller is None:
            out.append(
                Decision.from_arrays(
                    d.t_ns,
                    d.state,
                    -1,
                    math.inf,
                    False,
                    np.zeros((0, 3)),
                    np.zeros(0, dtype=np.int64),
                    -1,
                    d.controller_version,
                    d.scenario_hash,
                )
            )
            continue
        safe = np.array(got.safe, dtype=np.int64)
        out.append(
            Decision.from_arrays(
                d.t_ns,
                d.state,
                got.cell,
                got.value,
                got.winning,
                controller.inputs[safe],
                safe,
                got.chosen,
                d.controller_version,
                d.scenario_hash,
                chosen_input=controller.inputs[got.chosen] if got.chosen >= 0 else np.zeros(3),
            )
        )
    return out


def check_decisions(run: RunData, controllers: ControllerCache) -> Check:
    """Recompute every recorded decision at its recorded state (see module docstring)."""
    if not run.decisions:
        return Check("decisions", Status.SKIP, "the log holds no decisions")
    findings: list[Finding] = []
    before = controllers.syntheses
    for d, got, controller in _recomputed(run, controllers):
        if isinstance(got, str) or controller is None:
            findings.append(Finding(str(got), d.t_ns))
            continue
        found = _mismatch(d, got, controller)
        if found is not None:
            findings.append(found)
    n = len(run.decisions)
    synth = controllers.syntheses - before
    metrics = {"decisions": n, "mismatches": len(findings), "syntheses": synth}
    if findings:
        return Check(
            "decisions",
            Status.FAIL,
            f"{len(findings)} of {n} decisions differ, first at {time_s(findings[0].t_ns)}",
            tuple(findings),
            metrics,
        )
    return Check(
        "decisions", Status.PASS, f"{n} decisions reproduced ({synth} new syntheses)", (), metrics
    )


def decision_findings(recorded: tuple[Decision, ...], replayed: list[Decision]) -> list[Finding]:
    """Compare a re-run's decisions with the recorded ones, matched by time."""
    by_t = {d.t_ns: d for d in replayed}
    findings = []
    for d in recorded:
        other = by_t.pop(d.t_ns, None)
        if other is None:
            findings.append(Finding("decision: recorded but not taken in the re-run", d.t_ns))
        elif (other.chosen_index, other.value, other.cell) != (d.chosen_index, d.value, d.cell):
            findings.append(
                Finding(
                    f"decision: recorded chosen {d.chosen_index} value {d.value} cell {d.cell}, "
                    f"re-run chosen {other.chosen_index} value {other.value} cell {other.cell} "
                    f"at state {[round(v, 4) for v in other.state]}",
                    d.t_ns,
                )
            )
    findings.extend(Finding("decision: taken in the re-run, not recorded", t) for t in sorted(by_t))
    return findings
