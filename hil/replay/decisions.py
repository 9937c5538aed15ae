"""The decisions check: every recorded decision taken again with the current code.

At every recorded decision, the controller for the recorded obstacle layout is
synthesized anew (one per distinct layout, cached) and queried at the recorded
estimated state: cell, winning status, value, safe-input set and the input the
paper's J picks given the previous recorded choice. Any difference is a regression.

Every field of the recorded decision is also checked against the others and the
input grid (:func:`consistency`): the chosen index among the safe indices, the
chosen input its grid row, every safe input the row of its index, winning agreeing
with the value. So a corrupted or hand-edited decision is a regression even where
the replay agrees on the index.

Tolerances, both far below what a hand edit or a real change moves:

- input rows are compared within ``ROW_TOLERANCE`` (1e-9 m/s, rad/s): the grid is
  recomputed from the scenario and recorded as float64, so rows agree to a few ulp
  (~1e-16) on any machine;
- a replayed choice that differs from the recorded one but costs the same J within
  ``COST_TOLERANCE`` (relative 1e-9; J is a sum of ~6 products of O(1) numbers, its
  rounding ~1e-15) is a tie the other machine broke the other way: accepted and
  counted (``cost_ties``).

The stack re-run and the re-simulation take their own decisions, compared with the
recorded ones by :mod:`hil.replay.divergence`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from hil.bag.run_data import RunData
from hil.controllers.symbolic import (
    ControllerSources,
    NoWinningSetError,
    SymbolicAdapter,
    cost,
    j_select,
    wait_slowest,
)
from hil.core.arrays import FloatArray
from hil.core.records import Decision
from hil.core.samples import ObstacleLayout
from hil.replay.context import ReplayContext
from hil.replay.controllers import ControllerCache
from hil.replay.regression import Check, Finding, Status, time_s
from hil.runtime.protocols import SymbolicController
from hil.runtime.settings import NS_PER_S

ROW_TOLERANCE = 1e-9
"""Largest difference between a recorded input row and the grid's (m/s, rad/s)."""
COST_TOLERANCE = 1e-9
"""Relative difference of the cost J under which two inputs tie."""
BOUNDARY_TOLERANCE = 1e-9
"""Distance to a cell boundary (m in x and y, rad in heading) within which a decision is
accepted on either side.

The recorded state is read back bit for bit, but the cell it falls in comes from grid
arithmetic ((x - x0) / eta, floored) that another CPU, compiler (FMA) or libm may round
an ulp differently (~1e-15 m at the arena's scale), and a re-run estimate carries its own
rounding (~1e-12), a re-simulation on another x86_64 CPU up to 1.5e-10 m over a whole run
(measured); 1e-9 covers them with room, and is a million times below the millimetres a
real change of the code moves a state. A re-run decision taken the other way is accepted
only when the re-run's state is within it of the recorded one too."""


@dataclass(frozen=True, slots=True)
class Recomputed:
    """A decision recomputed with the current code at a recorded state.

    Attributes:
        cell: Flat cell index (-1 outside the grid).
        value: Value at the state (+inf outside the winning set).
        safe: Input-grid indices of the safe inputs, sorted (the staying ones where
            docking is not winning and the vessel can stay safe).
        chosen: Input-grid index of the chosen input, -1 for none.
        staying: The decision is the safety controller's (docking not winning).
    """

    cell: int
    value: float
    safe: tuple[int, ...]
    chosen: int
    staying: bool = False

    @property
    def winning(self) -> bool:
        """Whether the state is in the winning set."""
        return math.isfinite(self.value)


def recompute(
    controller: SymbolicController,
    state: FloatArray,
    previous: FloatArray,
    reference: int,
    first: bool,
) -> Recomputed:
    """Take the runtime's decision at `state` (3,) again.

    Given the previous choice (3,) for the cost J, the reference in force (input-grid
    index) and whether it was a first decision.

    The runtime's own call (:meth:`SymbolicController.decide`) with the choices the
    vessel makes by default: J among the safe inputs (:func:`j_select`), the slowest
    (:func:`wait_slowest`) among the staying ones; none in the target (value 0) or where
    nothing is safe.
    """
    a = controller.decide(state, reference, first, previous, j_select, wait_slowest)
    return Recomputed(
        a.cell, a.value, tuple(sorted(int(i) for i in a.inputs)), a.chosen, a.staying
    )


def _version_times(run: RunData) -> dict[int, int]:
    """Return when each controller version was first taken (ns; early or full)."""
    out: dict[int, int] = {}
    for ready in run.controllers_ready():
        out.setdefault(ready.version, ready.t_ns)
    return out


def _made(layouts: int, sources: ControllerSources) -> str:
    """Say how the controllers of the layouts new to this check were had."""
    if layouts == 0:
        return "no new layout"
    return f"{layouts} new layout{'s' if layouts != 1 else ''}: {sources.describe()}"


def layout_at(run: RunData, t_ns: int) -> ObstacleLayout | None:
    """Return the newest recorded layout stamped at or before `t_ns` (None before the first)."""
    layout = run.layout_in_force(t_ns)
    return None if layout is None else layout.as_obstacle_layout()


def _inputs(controller: SymbolicController, indices: tuple[int, ...]) -> list[list[float]]:
    return [[round(float(v), 6) for v in controller.inputs[i]] for i in indices]


def _row(values: Sequence[float]) -> list[float]:
    return [round(float(v), 6) for v in values]


def _same_row(a: Sequence[float], b: Sequence[float]) -> bool:
    return bool(np.all(np.abs(np.asarray(a, dtype=np.float64) - np.asarray(b)) <= ROW_TOLERANCE))


def consistency(d: Decision, inputs: FloatArray | None) -> list[tuple[str, str]]:
    """Check a recorded decision against itself and the input grid; return (field, problem)s.

    The chosen index must be among the safe indices and the chosen input its grid
    row (zeros and no safe input left unchosen when none is chosen); every safe
    input must be the grid row of its index; winning must agree with the value,
    and a state in the target or outside the winning set has no safe input.

    Args:
        d: The recorded decision.
        inputs: The controller's input grid (n, 3); None when no controller could be
            synthesized (only the checks that need no grid are made).
    """
    out: list[tuple[str, str]] = []
    if d.winning != math.isfinite(d.value):
        out.append(("winning", f"winning: recorded {d.winning} but value {d.value}"))
    indices = d.safe_input_indices
    # Outside the winning set, a decision lists inputs only when it waits on the safety
    # controller, and then it flies one of them.
    if (d.value == 0.0 or (math.isinf(d.value) and d.chosen_index < 0)) and indices:
        out.append((
            "safe_input_indices",
            f"safe_input_indices: {len(indices)} safe input(s) recorded at value {d.value}, "
            "where the controller has none",
        ))  # fmt: skip
    seen = _safe_rows(d, inputs, out)
    if d.chosen_index == -1:
        if any(d.chosen_input):
            out.append(("chosen_input", f"chosen_input: recorded {_row(d.chosen_input)} with "
                        "no chosen_index (-1)"))  # fmt: skip
        if indices:
            out.append(
                ("chosen_index", f"chosen_index: -1 (none) although {len(indices)} safe inputs")
            )
        return out
    _chosen_row(d, inputs, seen, out)
    return out


def _safe_rows(d: Decision, inputs: FloatArray | None, out: list[tuple[str, str]]) -> set[int]:
    """Check each listed safe input against its index; return the indices listed."""
    seen: set[int] = set()
    for k, (index, row) in enumerate(zip(d.safe_input_indices, d.safe_inputs, strict=True)):
        if index in seen:
            out.append(("safe_input_indices", f"safe_input_indices[{k}]: {index} listed twice"))
        seen.add(index)
        if inputs is None:
            continue
        if not 0 <= index < len(inputs):
            out.append((
                "safe_input_indices",
                f"safe_input_indices[{k}]: {index} outside the input grid of {len(inputs)}",
            ))  # fmt: skip
        elif not _same_row(row, inputs[index]):
            out.append((
                "safe_inputs",
                f"safe_inputs[{k}]: recorded {_row(row)} but input-grid row {index} is "
                f"{_row(inputs[index])}",
            ))  # fmt: skip
    return seen


def _chosen_row(
    d: Decision, inputs: FloatArray | None, seen: set[int], out: list[tuple[str, str]]
) -> None:
    """Check the chosen index among the safe ones and the chosen input its row."""
    chosen = d.chosen_index
    if chosen not in seen:
        out.append(("chosen_index", f"chosen_index: {chosen} is not among the safe_input_indices"))
    if inputs is not None:
        if not 0 <= chosen < len(inputs):
            out.append(
                ("chosen_index", f"chosen_index: {chosen} outside the input grid of {len(inputs)}")
            )
        elif not _same_row(d.chosen_input, inputs[chosen]):
            out.append((
                "chosen_input",
                f"chosen_input: recorded {_row(d.chosen_input)} but chosen_index {chosen} "
                f"is input-grid row {_row(inputs[chosen])}",
            ))  # fmt: skip
    elif chosen in seen:
        row = d.safe_inputs[d.safe_input_indices.index(chosen)]
        if not _same_row(d.chosen_input, row):
            out.append((
                "chosen_input",
                f"chosen_input: recorded {_row(d.chosen_input)} but the safe input of "
                f"chosen_index {chosen} is {_row(row)}",
            ))  # fmt: skip


def across_boundaries(
    controller: SymbolicController, state: FloatArray, cell: int, tol: float = BOUNDARY_TOLERANCE
) -> list[FloatArray]:
    """Return states within `tol` of `state` (3,) per axis that lie in another cell than `cell`.

    Each axis is moved by -tol, 0 or +tol (x, y in m, heading in rad): a state that far
    from a boundary has its neighbours across it among them. Empty when the state lies
    farther than `tol` from every boundary (the usual case).
    """
    out: list[FloatArray] = []
    seen = {cell}
    for dx in (-tol, 0.0, tol):
        for dy in (-tol, 0.0, tol):
            for dpsi in (-tol, 0.0, tol):
                moved = state + np.array([dx, dy, dpsi])
                other = controller.locate(moved)
                if other not in seen:
                    seen.add(other)
                    out.append(moved)
    return out


def is_cost_tie(controller: SymbolicController, a: int, b: int, previous: FloatArray) -> bool:
    """Whether inputs `a` and `b` cost the same J given `previous`, within COST_TOLERANCE."""
    if a < 0 or b < 0 or max(a, b) >= len(controller.inputs):
        return False
    ja, jb = cost(controller.inputs[[a, b]], previous)
    return bool(abs(ja - jb) <= COST_TOLERANCE * max(1.0, abs(ja), abs(jb)))


def mismatch(
    d: Decision, got: Recomputed, controller: SymbolicController, previous: FloatArray
) -> tuple[Finding | None, bool]:
    """Return the finding for `d` (None when it holds) and whether a cost tie was accepted."""
    recorded_safe = tuple(sorted(d.safe_input_indices))
    same_set = recorded_safe == got.safe
    tie = (
        d.chosen_index != got.chosen
        and same_set
        and d.chosen_index in got.safe
        and is_cost_tie(
            controller, d.chosen_index, got.chosen, np.zeros(3) if got.staying else previous
        )
    )
    fields = [
        name
        for name, same in (
            ("cell", d.cell == got.cell),
            ("winning", d.winning == got.winning),
            ("value", d.value == got.value),
            ("safe_input_indices", same_set),
            ("chosen_index", d.chosen_index == got.chosen or tie),
        )
        if not same
    ]
    inconsistent = consistency(d, controller.inputs)
    if not fields and not inconsistent:
        return None, tie
    only_rec = sorted(set(recorded_safe) - set(got.safe))
    only_new = sorted(set(got.safe) - set(recorded_safe))
    state = [round(v, 4) for v in d.state]
    parts = [text for _, text in inconsistent]
    if fields:
        parts.append(
            f"{', '.join(fields)} differ from the replay at state {state}: recorded chosen "
            f"{d.chosen_index} {_row(d.chosen_input)} value {d.value}, replayed chosen "
            f"{got.chosen}{_inputs(controller, (got.chosen,)) if got.chosen >= 0 else ''} "
            f"value {got.value}; safe set recorded {len(recorded_safe)}, replayed "
            f"{len(got.safe)} (only recorded {only_rec[:8]}, only replayed {only_new[:8]})"
        )
    finding = Finding(
        "; ".join(parts),
        d.t_ns,
        {
            "fields": sorted({*fields, *(name for name, _ in inconsistent)}),
            "differ": fields,
            "inconsistent": [text for _, text in inconsistent],
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
    return finding, tie


def _recomputed(
    run: RunData, controllers: ControllerCache
) -> Iterator[tuple[Decision, Recomputed | str, SymbolicAdapter | None, FloatArray]]:
    """Yield each recorded decision with its recomputation (or why there is none).

    The last item is the previous recorded choice the cost J was evaluated against.
    """
    previous = np.zeros(3)
    for d, controller in decision_controllers(run, controllers):
        if isinstance(controller, str):
            yield d, controller, None, previous
            continue
        yield (
            d,
            recompute(controller, np.array(d.state), previous, d.reference_index, d.first),
            controller,
            previous,
        )
        if d.chosen_index >= 0:
            previous = np.array(d.chosen_input)


def decision_controllers(
    run: RunData, controllers: ControllerCache
) -> Iterator[tuple[Decision, SymbolicAdapter | str]]:
    """Yield each recorded decision with the controller of its recorded layout.

    The controller is the current code's synthesis for the obstacle report the decision
    relied on (the recorded one of its stamp; a report from before the run, stamped
    earlier, is recorded when first seen) and the report age it records; a log without
    them gives the layout in force when the decision's controller version was swapped
    in and the scenario's age. Instead of it, one line saying why there is none (no
    layout recorded, no winning set now).
    """
    ready = _version_times(run)
    first = min((layout.t_ns for layout in run.layouts), default=0)
    for d in run.decisions:
        if d.report_t_ns >= 0:
            layout = layout_at(run, max(d.report_t_ns, first))
        else:
            layout = layout_at(run, ready.get(d.controller_version, d.t_ns))
        if layout is None:
            yield d, "no obstacle layout recorded before this decision"
            continue
        try:
            yield d, controllers(layout, d.report_age_s)
        except NoWinningSetError as err:
            yield d, f"recorded a decision, but now: {err}"


def relied_on_stale_report(d: Decision) -> Finding | None:
    """Return a finding when `d` relied on an obstacle report older than it was solved for.

    With obstacles that move, a decision's controller avoids where they may be up to its
    ``report_age_s`` (+ tau + late) after the report it relied on (``report_t_ns``); a
    decision taken later than that left what it assumed. The runtime refuses such a
    decision (``obstacles_stale``); one in a log is a regression. Compared exactly as the
    runtime does ((t - stamp) / 1e9 s against the age: integer nanoseconds, one division,
    the same on every machine). A log without the two fields is not judged here.
    """
    if d.report_age_s is None or d.report_t_ns < 0:
        return None
    age_s = (d.t_ns - d.report_t_ns) / NS_PER_S
    if age_s <= d.report_age_s:
        return None
    return Finding(
        f"decided on an obstacle report {age_s:.3f} s old (t={d.report_t_ns} ns), older than "
        f"the {d.report_age_s:g} s its controller was solved for: the moving obstacles may "
        "have left what it avoided",
        d.t_ns,
        {"fields": ["report_t_ns"], "report_age_s": d.report_age_s, "age_s": age_s},
    )


def replayed_decisions(run: RunData, controllers: ControllerCache) -> list[Decision]:
    """Return the decisions the current code takes at the recorded states, in order.

    A decision that cannot be recomputed (no layout, no winning set) comes back
    with no safe input and no choice, so it shows as different.
    """
    out = []
    for d, got, controller, _ in _recomputed(run, controllers):
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


def check_decisions(ctx: ReplayContext) -> Check:
    """Check every field of every recorded decision (see module docstring)."""
    run, controllers = ctx.run, ctx.controllers
    if not run.decisions:
        return Check("decisions", Status.SKIP, "the log holds no decisions")
    findings: list[Finding] = []
    ties: list[int] = []
    before = controllers.synthesizer.sources.copy()
    layouts_before = controllers.layouts
    boundary: list[int] = []
    tracks = controllers.scenario.tracks_obstacles
    for d, got, controller, previous in _recomputed(run, controllers):
        if tracks and (stale := relied_on_stale_report(d)) is not None:
            findings.append(stale)
        if isinstance(got, str) or controller is None:
            extra = [text for _, text in consistency(d, None)]
            findings.append(Finding("; ".join([str(got), *extra]), d.t_ns))
            continue
        found, tie = mismatch(d, got, controller, previous)
        if found is not None and found.data.get("differ") and not found.data.get("inconsistent"):
            # Within BOUNDARY_TOLERANCE of a cell boundary either side's decision holds.
            for state in across_boundaries(controller, np.array(d.state), got.cell):
                other = recompute(controller, state, previous, d.reference_index, d.first)
                again, tie = mismatch(d, other, controller, previous)
                if again is None:
                    found = None
                    boundary.append(d.t_ns)
                    break
        if found is not None:
            findings.append(found)
        if tie:
            ties.append(d.t_ns)
    n = len(run.decisions)
    sources = controllers.synthesizer.sources.minus(before)
    layouts = controllers.layouts - layouts_before
    metrics = {
        "decisions": n,
        "mismatches": len(findings),
        "syntheses": sources.solved,
        "controllers_from_store": sources.store,
        "new_layouts": layouts,
        "cost_ties": len(ties),
        "cost_tie_times_ns": ties,
        "boundary_decisions": len(boundary),
        "boundary_times_ns": boundary,
        "boundary_tolerance": BOUNDARY_TOLERANCE,
    }
    tie_note = (
        f"; {len(ties)} chose another input of equal cost J (tie within "
        f"{COST_TOLERANCE:g}, accepted), first at {time_s(ties[0])}"
        if ties
        else ""
    )
    if boundary:
        tie_note += (
            f"; {len(boundary)} taken within {BOUNDARY_TOLERANCE:g} of a cell boundary match "
            f"the cell on the other side (accepted either way), first at {time_s(boundary[0])}"
        )
    if findings:
        return Check(
            "decisions",
            Status.FAIL,
            f"{len(findings)} of {n} decisions differ or are inconsistent, first at "
            f"{time_s(findings[0].t_ns)}{tie_note}",
            tuple(findings),
            metrics,
        )
    return Check(
        "decisions",
        Status.PASS,
        f"{n} decisions reproduced, every field consistent ({_made(layouts, sources)}){tie_note}",
        (),
        metrics,
    )
