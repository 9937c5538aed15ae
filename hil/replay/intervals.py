"""The run judged interval by interval: from each recorded decision to the next.

For every recorded decision, over the interval it governs:

- successor containment: the estimated state one sampling time tau after the
  decision lies in the abstraction's successor cells of the decision cell under the
  chosen input (what the synthesis assumed; :mod:`hil.controllers.symbolic.abstraction`);
- tube containment: every estimated position within tau of the decision lies in
  the cells of the input's swept tube (what obstacle avoidance assumed);
- the tracking error over the interval (RMS and largest, yaw in deg/s) and the axes
  on which it left the synthesized margin after settling;
- a verdict: FAIL when a failed check names a time in the interval (a decision that
  differs, a re-run that departs), WARN when the margin was left or a containment
  does not hold (the guarantee does not cover the interval), else PASS.

Containment is judged on the recorded estimates, the states the controller saw, with
the current code's controller for the recorded layout; it is None (not judged) where
no input was chosen, no controller exists or the run ended before tau.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from hil.bag.run_data import RunData
from hil.core.records import Decision
from hil.core.tracking import AXES, for_display
from hil.replay.controllers import ControllerCache
from hil.replay.decisions import decision_controllers
from hil.replay.regression import Check, Interval, Status
from hil.runtime.assembly import SymbolicAdapter
from hil.scenarios import Scenario

FloatArray = NDArray[np.float64]
NS_PER_S = 1_000_000_000


def _estimate_at(run: RunData, t_ns: int, slack_ns: int) -> FloatArray | None:
    """Return the estimated pose (x, y, psi) within `slack_ns` of `t_ns`, or None."""
    t = run.estimate.t_ns
    if not len(t):
        return None
    k = int(np.argmin(np.abs(t - t_ns)))
    if abs(int(t[k]) - t_ns) > slack_ns:
        return None
    return np.asarray(run.estimate.values[k, :3], dtype=np.float64)


def successor_contained(adapter: SymbolicAdapter, d: Decision, after: FloatArray) -> bool | None:
    """Whether `after` (x, y, psi) lies in the successor cells of `d`'s cell and choice.

    Returns:
        None when not judged: no input chosen, an index outside the input grid, or
        the decision state outside the grid; False when `after` is outside the grid.
    """
    controller = adapter.controller
    tables, grid = controller.tables, controller.grid
    u = d.chosen_index
    cell = grid.cell_of(d.state)
    if u < 0 or u >= tables.n_inputs or cell is None:
        return None
    reached = grid.cell_of(after)
    if reached is None:
        return False
    (i, j, k), (i2, j2, k2) = cell, reached
    ox0, ox1, oy0, oy1 = (int(v) for v in tables.succ[k, u])
    h0, h1 = (int(v) for v in tables.heading[u])
    heading_ok = any((k + ok) % grid.npsi == k2 for ok in range(h0, h1 + 1))
    return ox0 <= i2 - i <= ox1 and oy0 <= j2 - j <= oy1 and heading_ok


def tube_contained(adapter: SymbolicAdapter, d: Decision, poses: FloatArray) -> bool | None:
    """Whether every pose (N, 3) lies in the cells of the swept tube of `d`'s choice.

    Returns:
        None when not judged (no input chosen, decision state outside the grid, no pose).
    """
    controller = adapter.controller
    tables, grid = controller.tables, controller.grid
    u = d.chosen_index
    cell = grid.cell_of(d.state)
    if u < 0 or u >= tables.n_inputs or cell is None or not len(poses):
        return None
    i, j, k = cell
    x0, n = int(tables.tube_x0[k, u]), int(tables.tube_n[k, u])
    for pose in poses:
        reached = grid.cell_of(pose)
        if reached is None:
            return False
        c = reached[0] - i - x0
        if not 0 <= c < n:
            return False
        lo, hi = (int(v) for v in tables.tube_y[k, u, c])
        if not lo <= reached[1] - j <= hi:
            return False
    return True


def _failed_times(checks: Sequence[Check]) -> list[int]:
    """Return the times named by the findings of failed checks."""
    return sorted(
        f.t_ns for c in checks if c.status is Status.FAIL for f in c.findings if f.t_ns is not None
    )


def judge_intervals(
    run: RunData,
    controllers: ControllerCache,
    scenario: Scenario,
    checks: Sequence[Check],
    settle_s: float = 1.0,
) -> tuple[Interval, ...]:
    """Judge every interval between recorded decisions (see module docstring).

    Args:
        run: The recorded run.
        controllers: The current code's controllers for the run's scenario.
        scenario: Its scenario (the margin).
        checks: The checks already run on the log; a FAIL finding marks its interval.
        settle_s: The margin is checked from this long after the decision on (s).
    """
    decisions = run.decisions
    if not decisions:
        return ()
    series = run.tracking_error()
    margin = scenario.margin.as_array()
    failed = np.array(_failed_times(checks), dtype=np.int64)
    est_t = run.estimate.t_ns
    period = int(np.median(np.diff(est_t))) if len(est_t) > 2 else NS_PER_S // 20
    out: list[Interval] = []
    for n, (d, adapter) in enumerate(decision_controllers(run, controllers)):
        end = decisions[n + 1].t_ns if n + 1 < len(decisions) else max(run.last_stamp_ns, d.t_ns)
        notes: list[str] = []
        succ: bool | None = None
        tube: bool | None = None
        if isinstance(adapter, SymbolicAdapter):
            tau_ns = round(adapter.controller.tables.tau_s * NS_PER_S)
            after = _estimate_at(run, d.t_ns + tau_ns, period // 2)
            succ = None if after is None else successor_contained(adapter, d, after)
            within = (est_t >= d.t_ns) & (est_t <= d.t_ns + tau_ns)
            if after is not None:
                tube = tube_contained(adapter, d, run.estimate.values[within, :3])
        else:
            notes.append(adapter)
        if succ is False:
            notes.append("the state after tau left the successor cells of the chosen input")
        if tube is False:
            notes.append("the path left the swept tube of the chosen input")
        mask = (series.t_ns >= d.t_ns) & (series.t_ns < max(end, d.t_ns + 1))
        err = series.error[mask]
        rms = peak = None
        exceeded: tuple[str, ...] = ()
        if len(err):
            rms_v = for_display(np.sqrt(np.mean(err**2, axis=0)))
            peak_v = for_display(np.abs(err).max(axis=0))
            rms = (float(rms_v[0]), float(rms_v[1]), float(rms_v[2]))
            peak = (float(peak_v[0]), float(peak_v[1]), float(peak_v[2]))
            settled = series.t_ns[mask] - d.t_ns >= round(settle_s * NS_PER_S)
            over = (np.abs(err) > margin) & settled[:, None]
            exceeded = tuple(AXES[int(k)] for k in np.flatnonzero(over.any(axis=0)))
        if exceeded:
            notes.append(f"tracking error left the margin on {', '.join(exceeded)}")
        in_interval = bool(np.any((failed >= d.t_ns) & (failed < max(end, d.t_ns + 1))))
        if in_interval:
            notes.insert(0, "a failed check names a time in this interval")
        status = (
            Status.FAIL
            if in_interval
            else Status.WARN
            if exceeded or succ is False or tube is False
            else Status.PASS
        )
        out.append(
            Interval(
                t_ns=d.t_ns,
                end_ns=end,
                state=d.state,
                chosen_index=d.chosen_index,
                chosen_input=d.chosen_input,
                successor_contained=succ,
                tube_contained=tube,
                tracking_rms=rms,
                tracking_max=peak,
                margin_exceeded=exceeded,
                status=status,
                notes=tuple(notes),
            )
        )
    return tuple(out)
