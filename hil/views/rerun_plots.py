"""The time series of a recorded run: ``plots/...`` and ``events`` in Rerun.

Velocity per axis (commanded and estimated), the tracking error of
:mod:`hil.core.tracking` (SI, yaw rate in rad/s like the velocity plots) with
the scenario's margin band, thruster commands and azimuth angles, the force
demand, the value at each decision, synthesis times and the events.
"""

from __future__ import annotations

import math

import numpy as np
import rerun as rr
from numpy.typing import NDArray

from hil.bag.run_data import RunData, Series
from hil.views.rerun_style import (
    AXES,
    LEVELS,
    finite_or_nan,
    send_scalars,
    time_column,
)

FloatArray = NDArray[np.float64]


def log_velocity(rec: rr.RecordingStream, run: RunData) -> int:
    """Log commanded (nu_ref) and estimated (nu_hat) velocity per axis."""
    rows = 0
    estimate_nu = Series(run.estimate.t_ns, run.estimate.values[:, 3:6])
    for k, (axis, _) in enumerate(AXES):
        rows += send_scalars(rec, f"plots/velocity/{axis}/commanded", run.reference, [k])
        rows += send_scalars(rec, f"plots/velocity/{axis}/estimated", estimate_nu, [k])
    return rows


def _margin_band(t_ns: NDArray[np.int64], margin: FloatArray, k: int) -> Series:
    """Return the band +-margin[k] at the times `t_ns` (first and last suffice)."""
    return Series(t_ns, np.tile([margin[k], -margin[k]], (len(t_ns), 1)))


def log_tracking_error(rec: rr.RecordingStream, run: RunData, margin: FloatArray | None) -> int:
    """Log the tracking error per axis (SI) with the scenario's margin band (+-margin).

    The error is :meth:`hil.bag.run_data.RunData.tracking_error`: each estimate
    against the reference in force at its time, ``nu_hat - nu_ref``.
    """
    tracking = run.tracking_error()
    error = Series(tracking.t_ns, tracking.error)
    if not len(error):
        return 0
    rows = 0
    for k, (axis, _) in enumerate(AXES):
        rows += send_scalars(rec, f"plots/tracking_error/{axis}/error", error, [k])
        if margin is not None:
            band = _margin_band(error.t_ns[[0, -1]], margin, k)
            rows += send_scalars(rec, f"plots/tracking_error/{axis}/margin", band)
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
