"""The run judged interval by interval: each recorded decision held to its contract.

Every recorded decision that chose an input promised, through its
:class:`~hil.controllers.symbolic.DecisionContract` (built with the current code's
controller for the recorded layout, from the recorded cell, choice, reference in force
and first flag; the judge the runtime monitor and the campaign share), over the
interval it governs:

- tube: the true centre in the swept tube's cells over [0, tau + late]; the estimate
  is within ``estimation_position_m`` of the true centre, so every recorded estimate
  sample of the interval (no settle window) farther than that from the tube cells is
  a violation (size in m);
- successor: the estimate at the next decision (or at tau + late when there is none)
  in the successor cells, position and heading (sizes in m and rad); not judged when
  the next decision came before tau (a re-decision cut the interval short);
- descent: the value there, with the chosen input in force, strictly below the
  decision's;
- time: the next decision at most tau + late after it (every budget is bounded over
  periods up to that long); a later one is a broken premise (a stalled loop; the runtime
  names it ``late_interval``), the size how much later (s);
- velocity: |nu_hat - nu_ref| per axis within the budget's envelope of the decision's
  class at that time into the interval, plus :data:`VELOCITY_ESTIMATE_TOLERANCE` for
  the velocity estimate's own error (size: the largest excess, surge/sway m/s, yaw deg/s),
  from :data:`EKF_STARTUP_S` after the run's first estimate on.

Any violation makes the interval FAIL and the ``contract`` check (:func:`check_contract`)
FAIL, naming the interval and the size; so does a failed check that names a time in
the interval. The tracking error over the interval (RMS and largest) is reported as
figures.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from hil.bag.run_data import RunData
from hil.controllers.symbolic import DecisionContract, SymbolicAdapter
from hil.core.arrays import FloatArray, IntArray
from hil.core.clock import NS_PER_S
from hil.core.records import Decision
from hil.core.tracking import AXES, DISPLAY_UNITS, TrackingSeries, for_display
from hil.core.transient import BudgetClass, TransientBudget
from hil.replay.context import ReplayContext
from hil.replay.controllers import ControllerCache
from hil.replay.decisions import decision_controllers
from hil.replay.regression import Check, Finding, Interval, Status, time_s
from hil.scenarios import Scenario

VELOCITY_ESTIMATE_TOLERANCE = (0.012, 0.010, 0.015)
"""Allowance for the EKF's own velocity error (surge m/s, sway m/s, yaw rate rad/s).

The envelopes bound the *true* |nu - nu_ref|; the log holds the estimate nu_hat, so
|nu_hat - nu_ref| <= envelope + |nu_hat - nu|. Measured on the simulated EKF in the
runtime's loop (|nu_hat - nu_true| at every tick, seeds 0-2, 40-60 s runs on a 0.1-m
grid of the coarse arena): largest 0.0055 m/s surge, 0.0048 m/s sway, 0.0071 rad/s yaw
rate once the filter has run :data:`EKF_STARTUP_S`; about 2x that, rounded up. The
budget's estimation bounds cover the pose only; when it carries a velocity bound this
should come from it.
"""

EKF_STARTUP_S = 0.5
"""Velocity is not judged this long after the run's first estimate (s).

The filter starts at rest at its first pose and converges within a few IMU samples:
in the same measurement its velocity error reached 0.095 m/s (surge and sway) in the
first 0.3 s of a run. That is the filter's start-up, not the low level's tracking; the
pose is judged from the first sample on.
"""


def _estimates_in(run: RunData, start_ns: int, stop_ns: int) -> tuple[
    NDArray[np.int64], FloatArray, FloatArray
]:
    """Return the estimate samples with start <= t <= stop: times, poses (N, 3), nu (N, 3)."""
    t = run.estimate.t_ns
    keep = (t >= start_ns) & (t <= stop_ns)
    values = np.asarray(run.estimate.values, dtype=np.float64)
    return t[keep], values[keep, :3], values[keep, 3:6]


def _estimate_at(run: RunData, t_ns: int, slack_ns: int) -> FloatArray | None:
    """Return the estimated pose (x, y, psi) within `slack_ns` of `t_ns`, or None."""
    t = run.estimate.t_ns
    if not len(t):
        return None
    k = int(np.argmin(np.abs(t - t_ns)))
    if abs(int(t[k]) - t_ns) > slack_ns:
        return None
    return np.asarray(run.estimate.values[k, :3], dtype=np.float64)


def contract_of(adapter: SymbolicAdapter, d: Decision) -> DecisionContract | None:
    """Return the contract of a recorded decision; None when it chose nothing.

    None too outside the grid or for an index the input grid does not hold.
    """
    n = adapter.controller.tables.n_inputs
    if not (0 <= d.chosen_index < n and 0 <= d.reference_index < n):
        return None
    return adapter.contract(
        np.array(d.state), d.chosen_index, d.reference_index, d.first, d.staying
    )


def budget_class(d: Decision) -> int | None:
    """Return the budget class of a recorded decision; None when it chose no input.

    2 (start) for a first decision, 0 (hold) when it kept the reference in force, else
    1 (change): the class its contract is built with.
    """
    if d.chosen_index < 0:
        return None
    if d.first:
        return 2
    return 0 if d.chosen_index == d.reference_index else 1


def envelope_bound(budget: TransientBudget, budget_class: int, since_s: FloatArray) -> FloatArray:
    """Return the judged bound on |nu_hat - nu_ref| per sample and axis, (N, 3).

    The envelope of the class at each time since the decision plus
    :data:`VELOCITY_ESTIMATE_TOLERANCE` (surge m/s, sway m/s, yaw rad/s).

    Args:
        budget: The scenario's transient budget.
        budget_class: The decision's class, clipped to the envelopes' classes.
        since_s: Time since the decision of each sample (s), shape (N,).
    """
    env = budget.envelopes[min(max(budget_class, 0), budget.envelopes.shape[0] - 1)]
    since = np.asarray(since_s, dtype=np.float64)
    bins = np.clip(np.floor(since / budget.bin_s).astype(np.int64), 0, env.shape[0] - 1)
    out: FloatArray = env[bins] + np.asarray(VELOCITY_ESTIMATE_TOLERANCE)[None, :]
    return out


def envelope_excess(
    budget: TransientBudget, budget_class: int, since_s: FloatArray, error: FloatArray
) -> FloatArray:
    """Return |error| - (envelope + tolerance) per sample and axis, (N, 3); > 0 violates.

    Args:
        budget: The scenario's transient budget.
        budget_class: The decision's class, clipped to the envelopes' classes.
        since_s: Time since the decision of each sample (s), shape (N,).
        error: nu_hat - nu_ref (surge m/s, sway m/s, yaw rad/s), shape (N, 3).
    """
    out: FloatArray = np.abs(error) - envelope_bound(budget, budget_class, since_s)
    return out


def _failed_times(checks: Sequence[Check]) -> list[int]:
    """Return the times named by the findings of failed checks."""
    return sorted(
        f.t_ns for c in checks if c.status is Status.FAIL for f in c.findings if f.t_ns is not None
    )


INTERRUPTIONS = frozenset(
    {"pose_lost", "thruster_failure", "no_controller", "not_winning", "stopped", "aborted",
     "timeout", "obstacles_stale"}
)
"""Event codes after which an interval no longer runs as its decision assumed (a hold,
thrust not delivered, a stop): it is judged up to the event, its end is not."""


def _interruption(run: RunData, start_ns: int, stop_ns: int) -> tuple[int, str] | None:
    """Return the first interrupting event (time, code) in [start_ns, stop_ns), if any."""
    for event in run.events:
        if start_ns <= event.t_ns < stop_ns and event.code in INTERRUPTIONS:
            return event.t_ns, event.code
    return None


@dataclass
class _Judged:
    """What judging one interval found (the fields of its :class:`Interval`)."""

    notes: list[str] = field(default_factory=list)
    tube: bool | None = None
    tube_m: float | None = None
    succ: bool | None = None
    succ_m: float | None = None
    heading_rad: float | None = None
    descent: bool | None = None
    exceeded: tuple[str, ...] = ()
    excess: tuple[float, float, float] | None = None
    late_s: float | None = None

    @property
    def broken(self) -> bool:
        """Whether the interval broke its contract."""
        return (
            self.tube is False or self.succ is False or self.descent is False
            or bool(self.exceeded) or self.late_s is not None
        )


def judge_intervals(
    run: RunData,
    controllers: ControllerCache,
    scenario: Scenario,
    checks: Sequence[Check],
) -> tuple[Interval, ...]:
    """Judge every interval between recorded decisions (see module docstring).

    Args:
        run: The recorded run.
        controllers: The current code's controllers for the run's scenario.
        scenario: Its scenario (the transient budget).
        checks: The checks already run on the log; a FAIL finding marks its interval.
    """
    decisions = run.decisions
    if not decisions:
        return ()
    series = run.tracking_error()
    failed = np.array(_failed_times(checks), dtype=np.int64)
    est_t = run.estimate.t_ns
    period = int(np.median(np.diff(est_t))) if len(est_t) > 2 else NS_PER_S // 20
    startup_ns = (int(est_t[0]) if len(est_t) else 0) + round(EKF_STARTUP_S * NS_PER_S)
    out: list[Interval] = []
    for n, (d, adapter) in enumerate(decision_controllers(run, controllers)):
        last = n + 1 >= len(decisions)
        end = max(run.last_stamp_ns, d.t_ns) if last else decisions[n + 1].t_ns
        judged = _Judged()
        if isinstance(adapter, str):
            judged.notes.append(adapter)
        interrupted = _interruption(run, d.t_ns, end)
        if interrupted is not None:
            judged.notes.append(f"interrupted by {interrupted[1]} at {time_s(interrupted[0])}")
        if isinstance(adapter, SymbolicAdapter):
            span = _Span(d.t_ns, end, last, interrupted, period, startup_ns)
            _judge_contract(run, scenario.transient, contract_of(adapter, d), span, judged)
        rms, peak = _tracking(series, d.t_ns, end)
        in_interval = bool(np.any((failed >= d.t_ns) & (failed < max(end, d.t_ns + 1))))
        if in_interval:
            judged.notes.insert(0, "a failed check names a time in this interval")
        out.append(Interval(
            t_ns=d.t_ns, end_ns=end, state=d.state, chosen_index=d.chosen_index,
            chosen_input=d.chosen_input, successor_contained=judged.succ,
            tube_contained=judged.tube, value_decreased=judged.descent,
            tube_distance_m=judged.tube_m, successor_distance_m=judged.succ_m,
            heading_distance_rad=judged.heading_rad, tracking_rms=rms, tracking_max=peak,
            envelope_exceeded=judged.exceeded, envelope_excess=judged.excess,
            status=Status.FAIL if in_interval or judged.broken else Status.PASS,
            notes=tuple(judged.notes), late_s=judged.late_s,
        ))  # fmt: skip
    return tuple(out)


@dataclass(frozen=True, slots=True)
class _Span:
    """One interval's times (ns): from its decision to the next, and what cut it."""

    start_ns: int
    end_ns: int
    last: bool
    interrupted: tuple[int, str] | None
    period_ns: int
    startup_ns: int


def _judge_contract(
    run: RunData, budget: TransientBudget, contract: DecisionContract | None, span: _Span,
    judged: _Judged,
) -> None:
    """Judge one interval against its decision's contract: time, tube, envelope, successor."""
    if contract is None:
        return
    notes = judged.notes
    horizon_ns = round((contract.tau_s + contract.late_s) * NS_PER_S)
    held_ns = span.end_ns - span.start_ns
    if not span.last and span.interrupted is None and held_ns > horizon_ns:
        judged.late_s = (held_ns - horizon_ns) / NS_PER_S
        notes.append(
            f"input held {held_ns / NS_PER_S:.3f} s, past tau + late = "
            f"{horizon_ns / NS_PER_S:g} s by {judged.late_s:.3f} s: a broken premise "
            "(the loop stalled); no budget covers this interval"
        )
    stop = min(span.end_ns, span.start_ns + horizon_ns)
    if span.interrupted is not None:
        stop = min(stop, span.interrupted[0])
    t, poses, nu = _estimates_in(run, span.start_ns, stop)
    if len(t):
        _judge_tube(budget, contract, span, (t, poses, nu), judged)
    tau_ns = round(contract.tau_s * NS_PER_S)
    cut_short = (
        not span.last and span.end_ns < span.start_ns + tau_ns - span.period_ns // 2
    ) or span.interrupted is not None
    when = span.start_ns + horizon_ns if span.last else span.end_ns
    after = None if cut_short else _estimate_at(run, when, span.period_ns // 2 + 1)
    if after is not None:
        _judge_successor(contract, after[None, :], when, judged)


def _judge_tube(
    budget: TransientBudget,
    contract: DecisionContract,
    span: _Span,
    estimates: tuple[IntArray, FloatArray, FloatArray],
    judged: _Judged,
) -> None:
    """Judge the estimates (t (N,), poses (N, 3), nu (N, 3)) against the tube and envelope."""
    t, poses, nu = estimates
    dist = contract.tube_distance_m(poses)
    judged.tube_m = float(dist.max())
    judged.tube = judged.tube_m <= budget.estimation_position_m
    if not judged.tube:
        k = int(np.argmax(dist))
        judged.notes.append(
            f"estimate {judged.tube_m:.4f} m from the tube cells at {time_s(int(t[k]))} "
            f"(estimation bound {budget.estimation_position_m:.4f} m)"
        )
    over = envelope_excess(
        budget, contract.budget_class, (t - span.start_ns) / NS_PER_S, nu - contract.nu_ref
    )
    over[t < span.startup_ns] = -np.inf
    worst = for_display(np.maximum(over.max(axis=0), 0.0))
    judged.excess = (float(worst[0]), float(worst[1]), float(worst[2]))
    judged.exceeded = tuple(AXES[k] for k in np.flatnonzero((over > 0.0).any(axis=0)))
    if judged.exceeded:
        judged.notes.append(
            "velocity error beyond the envelope + estimate tolerance on "
            + ", ".join(
                f"{AXES[k]} by {worst[k]:.4f} {DISPLAY_UNITS[k]}"
                for k in range(3)
                if AXES[k] in judged.exceeded
            )
        )


def _judge_successor(
    contract: DecisionContract, pose: FloatArray, when: int, judged: _Judged
) -> None:
    """Judge the next decision's estimated pose (1, 3) at `when` (ns): successor, descent."""
    judged.succ = bool(contract.in_successor(pose)[0])
    judged.succ_m = float(contract.successor_distance_m(pose)[0])
    judged.heading_rad = float(contract.heading_distance_rad(pose)[0])
    judged.descent = bool(contract.value_decreases(pose)[0])
    if not judged.succ:
        judged.notes.append(
            f"estimate at {time_s(when)} {judged.succ_m:.4f} m and {judged.heading_rad:.4f} "
            "rad outside the successor cells"
        )
    if not judged.descent:
        v = int(contract.end_values(pose)[0])
        first = contract.budget_class == BudgetClass.START
        judged.notes.append(
            f"value {'losing' if v < 0 else v} at {time_s(when)} not below the "
            f"decision's {'win' if first else contract.value}"
        )


def _tracking(
    series: TrackingSeries, start_ns: int, end_ns: int
) -> tuple[tuple[float, float, float] | None, tuple[float, float, float] | None]:
    """Return the interval's tracking error RMS and largest per axis (display units)."""
    err = series.error[(series.t_ns >= start_ns) & (series.t_ns < max(end_ns, start_ns + 1))]
    if not len(err):
        return None, None
    rms = for_display(np.sqrt(np.mean(err**2, axis=0)))
    peak = for_display(np.abs(err).max(axis=0))
    return (float(rms[0]), float(rms[1]), float(rms[2])), (
        float(peak[0]), float(peak[1]), float(peak[2])
    )


def check_contract(ctx: ReplayContext) -> Check:
    """Judge every interval of the run (:func:`judge_intervals`) and give the verdict.

    The check carries the judged intervals (``Check.intervals``).
    """
    intervals = judge_intervals(ctx.run, ctx.controllers, ctx.scenario, ctx.earlier)
    return dataclasses.replace(contract_verdict(intervals), intervals=intervals)


def contract_verdict(intervals: Sequence[Interval]) -> Check:
    """Return the ``contract`` check: FAIL naming every interval that broke its contract."""
    judged = [i for i in intervals if i.tube_contained is not None]
    if not judged:
        return Check("contract", Status.SKIP, "no interval with a chosen input to judge")
    broken = [
        i
        for i in judged
        if i.tube_contained is False
        or i.successor_contained is False
        or i.value_decreased is False
        or i.envelope_exceeded
        or i.late_s is not None
    ]
    worst_tube = max((i.tube_distance_m or 0.0 for i in judged), default=0.0)
    metrics = {
        "intervals_judged": len(judged),
        "intervals_failed": len(broken),
        "tube_exits": sum(i.tube_contained is False for i in judged),
        "successor_misses": sum(i.successor_contained is False for i in judged),
        "value_not_decreasing": sum(i.value_decreased is False for i in judged),
        "envelope_exceeded": sum(bool(i.envelope_exceeded) for i in judged),
        "late_intervals": sum(i.late_s is not None for i in judged),
        "worst_late_s": max((i.late_s or 0.0 for i in judged), default=0.0),
        "worst_tube_distance_m": worst_tube,
        "velocity_estimate_tolerance": list(VELOCITY_ESTIMATE_TOLERANCE),
    }
    findings = tuple(
        Finding(
            f"interval {time_s(i.t_ns)}..{i.end_ns / NS_PER_S:.3f} s: " + "; ".join(
                note for note in i.notes if note != "a failed check names a time in this interval"
            ),
            i.t_ns,
            {
                "end_ns": i.end_ns,
                "tube_distance_m": i.tube_distance_m,
                "successor_distance_m": i.successor_distance_m,
                "heading_distance_rad": i.heading_distance_rad,
                "value_decreased": i.value_decreased,
                "envelope_excess": i.envelope_excess,
                "late_s": i.late_s,
            },
        )
        for i in broken
    )
    if not broken:
        return Check(
            "contract",
            Status.PASS,
            f"{len(judged)} intervals kept their contracts (tube, successor, value, "
            f"velocity envelope, time); estimate at most {worst_tube:.4f} m from its tube",
            (),
            metrics,
        )
    return Check(
        "contract",
        Status.FAIL,
        f"{len(broken)} of {len(judged)} intervals broke their contract",
        findings,
        metrics,
    )


__all__ = [
    "EKF_STARTUP_S",
    "VELOCITY_ESTIMATE_TOLERANCE",
    "budget_class",
    "check_contract",
    "contract_of",
    "contract_verdict",
    "envelope_bound",
    "envelope_excess",
    "judge_intervals",
]
