"""How hil's Rerun entities look and how rows go out: the shared part of the views.

The run's time axis (:data:`TIMELINE`, the run clock as a duration), colours,
the static look of every time-varying entity (:func:`log_styles`), and the two
ways rows are sent (:func:`send_strips`, :func:`send_scalars`, whole columns with
``send_columns``). Entity paths mirror frames (see :mod:`hil.views.rerun_export`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import rerun as rr
from numpy.typing import NDArray

from hil.bag.run_data import Series
from hil.core.arrays import FloatArray
from hil.core.records import Decision, EventLevel
from hil.views.controller_view import predicted_arcs

TIMELINE = "run_time"
"""The run clock (duration since the run started)."""
APPLICATION_ID = "hil"

AXES = (("surge", "u (m/s)"), ("sway", "v (m/s)"), ("yaw_rate", "r (rad/s)"))
WORLD_COORDINATES = rr.ViewCoordinates.RIGHT_HAND_Z_DOWN
"""The arena frame as Rerun sees it: x north, y east, z down (NED-like)."""
_Z_ARCS = -0.01  # z is down: the predicted arcs float just above the arena lines
_ARC_POINTS = 16

GREY = (150, 150, 150)
RED = (200, 40, 40)
ORANGE = (235, 150, 40)
GREEN = (40, 170, 70)
BLUE = (40, 110, 220)
CYAN = (60, 190, 210)
MAGENTA = (210, 60, 200)

LEVELS = {
    EventLevel.DEBUG: "DEBUG",
    EventLevel.INFO: "INFO",
    EventLevel.WARN: "WARN",
    EventLevel.ERROR: "ERROR",
    EventLevel.FATAL: "CRITICAL",
}


def time_column(t_ns: NDArray[np.int64]) -> rr.TimeColumn:
    """Return times (ns) (N,) as a column of :data:`TIMELINE`."""
    return rr.TimeColumn(
        TIMELINE, duration=np.asarray(t_ns, dtype=np.int64).astype("timedelta64[ns]")
    )


def closed_strip(xy: FloatArray, z: float = 0.0) -> FloatArray:
    """Return a polygon (n, 2) as a closed 3-D line strip, shape (n + 1, 3)."""
    ring = np.vstack([xy, xy[:1]])
    out: FloatArray = np.column_stack([ring, np.full(len(ring), z)])
    return out


def rectangle_xy(x: tuple[float, float], y: tuple[float, float]) -> FloatArray:
    """Return the corners of the rectangle x-range by y-range (m), shape (4, 2)."""
    return np.array([[x[0], y[0]], [x[1], y[0]], [x[1], y[1]], [x[0], y[1]]], dtype=np.float64)


Color = tuple[int, int, int]

_STRIP_STYLES: dict[str, tuple[Color, float]] = {
    "world/arena/obstacles/real": (RED, 0.025),
    "world/arena/obstacles/inflated": (ORANGE, 0.01),
    "world/controller/safe_inputs": (GREY, 0.006),
    "world/controller/chosen_input": (MAGENTA, 0.018),
    "world/replay/safe_inputs": (CYAN, 0.004),
    "world/replay/chosen_input": (ORANGE, 0.012),
}
"""Line strips over time: entity -> (color, radius in m)."""


def _series_styles() -> dict[str, tuple[tuple[str, ...], tuple[Color, ...]]]:
    """Return plot entity -> (line names, line colors)."""
    out: dict[str, tuple[tuple[str, ...], tuple[Color, ...]]] = {}
    for axis, label in AXES:
        out[f"plots/velocity/{axis}/commanded"] = ((f"commanded {label}",), (MAGENTA,))
        out[f"plots/velocity/{axis}/estimated"] = ((f"estimated {label}",), (BLUE,))
        out[f"plots/tracking_error/{axis}/error"] = ((f"error {label}",), (BLUE,))
        out[f"plots/tracking_error/{axis}/envelope"] = (("+envelope", "-envelope"), (RED, RED))
    out["plots/thrusters/commands"] = (("tunnel", "port", "starboard"), (ORANGE, RED, GREEN))
    out["plots/thrusters/azimuth_deg"] = (
        ("port angle (deg)", "starboard angle (deg)"),
        (RED, GREEN),
    )
    out["plots/force"] = (("X (N)", "Y (N)", "N (N m)"), (RED, GREEN, BLUE))
    out["plots/value"] = (("V (steps of tau)",), (GREEN,))
    out["plots/synthesis_time_s"] = (("synthesis (s)",), (ORANGE,))
    out["plots/replay/differs"] = (("replay differs (1)",), (RED,))
    return out


def log_styles(rec: rr.RecordingStream) -> int:
    """Log the static look of every time-varying entity (names, colors, widths)."""
    styles = _series_styles()
    for entity, (names, colors) in styles.items():
        rec.log(entity, rr.SeriesLines(names=names, colors=colors, widths=[1.5]), static=True)
    for entity, (color, radius_m) in _STRIP_STYLES.items():
        rec.log(entity, rr.LineStrips3D.from_fields(colors=[color], radii=[radius_m]), static=True)
    rec.log(
        "world/pose_samples", rr.Points3D.from_fields(colors=[CYAN], radii=[0.015]), static=True
    )
    rec.log(
        "world/replay/differs", rr.Points3D.from_fields(colors=[RED], radii=[0.12]), static=True
    )
    return len(styles) + len(_STRIP_STYLES) + 2


def send_strips(
    rec: rr.RecordingStream,
    entity: str,
    t_ns: Sequence[int],
    rows: Sequence[Sequence[FloatArray]],
) -> int:
    """Send line strips over time: row i holds the strips `rows[i]` (each (n, 3))."""
    if not rows:
        return 0
    strips = [s for row in rows for s in row]
    rec.send_columns(
        entity,
        indexes=[time_column(np.asarray(t_ns, dtype=np.int64))],
        columns=rr.LineStrips3D.columns(strips=strips).partition([len(r) for r in rows]),
    )
    return len(rows)


def send_scalars(
    rec: rr.RecordingStream,
    entity: str,
    series: Series,
    columns: Sequence[int] | None = None,
    scale: float = 1.0,
) -> int:
    """Send columns of `series` (all when None) as one multi-line plot entity."""
    if not len(series):
        return 0
    cols = list(range(series.values.shape[1])) if columns is None else list(columns)
    values = np.ascontiguousarray(series.values[:, cols] * scale)
    rec.send_columns(
        entity, indexes=[time_column(series.t_ns)], columns=rr.Scalars.columns(scalars=values)
    )
    return len(series)


def decision_strips(decision: Decision, tau_s: float) -> tuple[list[FloatArray], list[FloatArray]]:
    """Return the arcs of the safe inputs and of the chosen input (none if none), each (n, 3)."""
    arcs = predicted_arcs(decision.state, decision.safe_inputs_array(), tau_s, _ARC_POINTS)
    safe = [np.column_stack([a, np.full(len(a), _Z_ARCS)]) for a in arcs]
    if decision.chosen_index < 0:
        return safe, []
    arc = predicted_arcs(decision.state, np.array([decision.chosen_input]), tau_s, _ARC_POINTS)[0]
    return safe, [np.column_stack([arc, np.full(len(arc), 2 * _Z_ARCS)])]


def finite_or_nan(value: float) -> float:
    """Return `value`, or NaN for an infinite one (Rerun draws no point then)."""
    return value if math.isfinite(value) else math.nan
