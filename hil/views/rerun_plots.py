"""The time series of a recorded run: ``plots/...`` and ``events`` in Rerun.

Velocity per axis (commanded and estimated), the tracking error of
:mod:`hil.core.tracking` (SI, yaw rate in rad/s like the velocity plots) with
the velocity envelope replay judges it against (the transient budget's envelope of
the class of the decision in force, at the time since it, plus the velocity
estimate's tolerance), thruster commands and azimuth angles, the force demand, the
value at each decision, synthesis times, the events, and for a run with the qtm pose
backend QTM's frames as received (``plots/qtm/...``: position in mm, NaN where QTM lost
the body; drops and losses counted by hil; QTM's own drop and out-of-sync rates).
"""

from __future__ import annotations

import math

import numpy as np
import rerun as rr
from numpy.typing import NDArray

from hil.bag.run_data import RunData, Series
from hil.core.arrays import FloatArray
from hil.core.clock import NS_PER_S
from hil.core.timeline import in_force
from hil.core.transient import TransientBudget
from hil.replay.intervals import budget_class, envelope_bound
from hil.views.rerun_style import (
    AXES,
    LEVELS,
    finite_or_nan,
    send_scalars,
    time_column,
)


def log_velocity(rec: rr.RecordingStream, run: RunData) -> int:
    """Log commanded (nu_ref) and estimated (nu_hat) velocity per axis."""
    rows = 0
    estimate_nu = Series(run.estimate.t_ns, run.estimate.values[:, 3:6])
    for k, (axis, _) in enumerate(AXES):
        rows += send_scalars(rec, f"plots/velocity/{axis}/commanded", run.reference, [k])
        rows += send_scalars(rec, f"plots/velocity/{axis}/estimated", estimate_nu, [k])
    return rows




def envelope_band(run: RunData, budget: TransientBudget, t_ns: NDArray[np.int64]) -> FloatArray:
    """Return the bound replay judges |nu_hat - nu_ref| against at each time, (N, 3).

    The envelope of the class of the decision in force (hold, change, start) at the
    time since it, plus the velocity estimate's tolerance
    (:func:`hil.replay.intervals.envelope_bound`); NaN before the first decision and
    where the decision in force chose no input.
    """
    times = np.asarray(t_ns, dtype=np.int64)
    out: FloatArray = np.full((len(times), 3), np.nan)
    decisions = run.decisions
    if not decisions or not len(times):
        return out
    starts = np.array([d.t_ns for d in decisions], dtype=np.int64)
    decision_at = in_force(starts, times)
    for n, d in enumerate(decisions):
        cls = budget_class(d)
        mask = decision_at == n
        if cls is not None and mask.any():
            out[mask] = envelope_bound(budget, cls, (times[mask] - d.t_ns) / NS_PER_S)
    return out


def log_tracking_error(
    rec: rr.RecordingStream, run: RunData, budget: TransientBudget | None
) -> int:
    """Log the tracking error per axis (SI) with the velocity envelope band (+-bound).

    The error is :meth:`hil.bag.run_data.RunData.tracking_error`: each estimate
    against the reference in force at its time, ``nu_hat - nu_ref``; the band is
    :func:`envelope_band` at the same times (left out when `budget` is None).
    """
    tracking = run.tracking_error()
    error = Series(tracking.t_ns, tracking.error)
    if not len(error):
        return 0
    bound = envelope_band(run, budget, error.t_ns) if budget is not None else None
    rows = 0
    for k, (axis, _) in enumerate(AXES):
        rows += send_scalars(rec, f"plots/tracking_error/{axis}/error", error, [k])
        if bound is not None:
            band = Series(error.t_ns, np.column_stack([bound[:, k], -bound[:, k]]))
            rows += send_scalars(rec, f"plots/tracking_error/{axis}/envelope", band)
    return rows


def log_thrusters(rec: rr.RecordingStream, run: RunData) -> int:
    """Log the normalized thruster commands and the azimuth angles (deg)."""
    rows = send_scalars(rec, "plots/thrusters/commands", run.thrusters, [0, 1, 2])
    rows += send_scalars(
        rec, "plots/thrusters/azimuth_deg", run.thrusters, [3, 4], scale=180.0 / math.pi
    )
    return rows


def log_force(rec: rr.RecordingStream, run: RunData) -> int:
    """Log the generalized force demand tau (X N, Y N, N N m)."""
    return send_scalars(rec, "plots/force", run.force)


def log_value(rec: rr.RecordingStream, run: RunData) -> int:
    """Log the value function (steps to the target) at each decision; NaN when not winning."""
    if not run.decisions:
        return 0
    t_ns = np.array([d.t_ns for d in run.decisions], dtype=np.int64)
    value = np.array([finite_or_nan(d.value) for d in run.decisions])
    return send_scalars(rec, "plots/value", Series(t_ns, value[:, None]))


def log_synthesis_time(rec: rr.RecordingStream, run: RunData) -> int:
    """Log the wall time of each re-synthesis (s)."""
    times = run.synthesis_times()
    if not times:
        return 0
    series = Series(
        np.array([s.t_ns for s in times], dtype=np.int64), np.array([[s.seconds] for s in times])
    )
    return send_scalars(rec, "plots/synthesis_time_s", series)


def log_events(rec: rr.RecordingStream, run: RunData) -> int:
    """Log events and faults as text log entries with their level."""
    if not run.events:
        return 0
    t_ns = np.array([e.t_ns for e in run.events], dtype=np.int64)
    text = [f"{e.code}: {e.text}" for e in run.events]
    levels = [LEVELS.get(e.level, "INFO") for e in run.events]
    rec.send_columns(
        "events", indexes=[time_column(t_ns)], columns=rr.TextLog.columns(text=text, level=levels)
    )
    return len(run.events)


def log_qtm(rec: rr.RecordingStream, run: RunData) -> int:
    """Log QTM's 6D frames as received: position (mm), drops and losses, QTM's rates."""
    if not run.qtm:
        return 0
    t_ns = np.array([s.t_ns for s in run.qtm], dtype=np.int64)
    position = np.array([s.position_mm for s in run.qtm], dtype=np.float64)
    counts = np.array([(s.drops, s.lost) for s in run.qtm], dtype=np.float64)
    rates = np.array([(s.drop_rate, s.out_of_sync_rate) for s in run.qtm], dtype=np.float64)
    rows = send_scalars(rec, "plots/qtm/position_mm", Series(t_ns, position))
    rows += send_scalars(rec, "plots/qtm/drops_and_losses", Series(t_ns, counts))
    rows += send_scalars(rec, "plots/qtm/qtm_drop_and_out_of_sync_rate", Series(t_ns, rates))
    return rows
