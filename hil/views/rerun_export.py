"""Turn a recorded run into a Rerun recording: arena, vessel, controller view, time series.

Every Rerun call of hil lives in this module (the Rerun API moves fast). One
``log_<stream>()`` per stream; whole series go out with ``send_columns`` on the
run's own time axis (:data:`TIMELINE`, the run clock as a duration), calibration
and the arena with ``static=True``, and :func:`blueprint` lays the viewer out.

Entity paths mirror frames:

- ``world``: the arena frame, shown top-down like the paper's figures (x right,
  y up); ``world/arena/{boundary,target/T1,target/T2,obstacles/real,obstacles/inflated}``;
- ``world/vessel``: the body frame, one transform per measured pose; its child
  ``world/vessel/hull`` is the hull outline in the body frame;
- ``world/pose_samples``, ``world/trajectory``: the measured poses and the
  estimated path, in the arena frame;
- ``world/controller/{safe_inputs,chosen_input,winning_set}``: the controller's
  view at each decision;
- ``plots/...``: velocity per axis, tracking error with the margin band,
  thrusters, azimuth angles, force, value, synthesis time; ``events``: faults.
"""

from __future__ import annotations

import math
import os
import shutil
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from numpy.typing import NDArray

from hil.bag.run_data import Layout, RunData, Series, synthesis_time
from hil.core.records import Decision, Event, EventLevel
from hil.core.samples import ImuSample, ObstacleLayout, PoseSample, ThrusterCommand
from hil.runtime.stack import RunLog
from hil.scenarios import Hull, Scenario
from hil.views.controller_view import (
    ControllerView,
    WinningSlice,
    inflated_outlines,
    predicted_arcs,
)

FloatArray = NDArray[np.float64]

TIMELINE = "run_time"
"""The run clock (duration since the run started)."""
APPLICATION_ID = "hil"

_AXES = (("surge", "u (m/s)"), ("sway", "v (m/s)"), ("yaw_rate", "r (rad/s)"))
_Z_GRID = -0.02  # the winning set lies just under the arena lines
_Z_ARCS = 0.01
_ARC_POINTS = 16

_GREY = (150, 150, 150)
_RED = (200, 40, 40)
_ORANGE = (235, 150, 40)
_GREEN = (40, 170, 70)
_BLUE = (40, 110, 220)
_CYAN = (60, 190, 210)
_MAGENTA = (210, 60, 200)

_LEVELS = {
    EventLevel.DEBUG: "DEBUG",
    EventLevel.INFO: "INFO",
    EventLevel.WARN: "WARN",
    EventLevel.ERROR: "ERROR",
    EventLevel.FATAL: "CRITICAL",
}


@dataclass(frozen=True, slots=True)
class ExportStats:
    """What an export wrote.

    Attributes:
        path: The ``.rrd`` file (None when streamed to a viewer).
        bytes: File size (bytes; 0 when streamed).
        rows: Rows sent over all entities.
        seconds: Wall time of the export (s).
    """

    path: Path | None
    bytes: int
    rows: int
    seconds: float


def _time(t_ns: NDArray[np.int64]) -> rr.TimeColumn:
    return rr.TimeColumn(
        TIMELINE, duration=np.asarray(t_ns, dtype=np.int64).astype("timedelta64[ns]")
    )


def _closed(xy: FloatArray, z: float = 0.0) -> FloatArray:
    """Return a polygon (n, 2) as a closed 3-D line strip, shape (n + 1, 3)."""
    ring = np.vstack([xy, xy[:1]])
    out: FloatArray = np.column_stack([ring, np.full(len(ring), z)])
    return out


def _rect(x: tuple[float, float], y: tuple[float, float]) -> FloatArray:
    return np.array([[x[0], y[0]], [x[1], y[0]], [x[1], y[1]], [x[0], y[1]]], dtype=np.float64)


_Color = tuple[int, int, int]

_STRIP_STYLES: dict[str, tuple[_Color, float]] = {
    "world/arena/obstacles/real": (_RED, 0.025),
    "world/arena/obstacles/inflated": (_ORANGE, 0.01),
    "world/controller/safe_inputs": (_GREY, 0.006),
    "world/controller/chosen_input": (_MAGENTA, 0.018),
    "world/replay/safe_inputs": (_CYAN, 0.004),
    "world/replay/chosen_input": (_ORANGE, 0.012),
}
"""Line strips over time: entity -> (color, radius in m)."""


def _series_styles() -> dict[str, tuple[tuple[str, ...], tuple[_Color, ...]]]:
    """Return plot entity -> (line names, line colors)."""
    out: dict[str, tuple[tuple[str, ...], tuple[_Color, ...]]] = {}
    for axis, label in _AXES:
        out[f"plots/velocity/{axis}/commanded"] = ((f"commanded {label}",), (_MAGENTA,))
        out[f"plots/velocity/{axis}/estimated"] = ((f"estimated {label}",), (_BLUE,))
        out[f"plots/tracking_error/{axis}/error"] = ((f"error {label}",), (_BLUE,))
        out[f"plots/tracking_error/{axis}/margin"] = (("+margin", "-margin"), (_RED, _RED))
    out["plots/thrusters/commands"] = (("tunnel", "port", "starboard"), (_ORANGE, _RED, _GREEN))
    out["plots/thrusters/azimuth_deg"] = (
        ("port angle (deg)", "starboard angle (deg)"),
        (_RED, _GREEN),
    )
    out["plots/force"] = (("X (N)", "Y (N)", "N (N m)"), (_RED, _GREEN, _BLUE))
    out["plots/value"] = (("V (steps of tau)",), (_GREEN,))
    out["plots/synthesis_time_s"] = (("synthesis (s)",), (_ORANGE,))
    out["plots/replay/differs"] = (("replay differs (1)",), (_RED,))
    return out


def log_styles(rec: rr.RecordingStream) -> int:
    """Log the static look of every time-varying entity (names, colors, widths)."""
    styles = _series_styles()
    for entity, (names, colors) in styles.items():
        rec.log(entity, rr.SeriesLines(names=names, colors=colors, widths=[1.5]), static=True)
    for entity, (color, radius_m) in _STRIP_STYLES.items():
        rec.log(entity, rr.LineStrips3D.from_fields(colors=[color], radii=[radius_m]), static=True)
    rec.log(
        "world/pose_samples", rr.Points3D.from_fields(colors=[_CYAN], radii=[0.015]), static=True
    )
    rec.log(
        "world/replay/differs", rr.Points3D.from_fields(colors=[_RED], radii=[0.12]), static=True
    )
    return len(styles) + len(_STRIP_STYLES) + 2


def _strip_rows(
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
        indexes=[_time(np.asarray(t_ns, dtype=np.int64))],
        columns=rr.LineStrips3D.columns(strips=strips).partition([len(r) for r in rows]),
    )
    return len(rows)


def _scalars(
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
        entity, indexes=[_time(series.t_ns)], columns=rr.Scalars.columns(scalars=values)
    )
    return len(series)


# ---------------------------------------------------------------- the arena


def log_arena(rec: rr.RecordingStream, scenario: Scenario | None) -> int:
    """Log the boundary and the targets T1 (real) and T2 (abstract), static.

    Without a scenario (an unknown one) nothing is drawn.
    """
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    if scenario is None:
        return 0
    boundary = _rect(scenario.x_range_m, scenario.y_range_m)
    rec.log(
        "world/arena/boundary",
        rr.LineStrips3D([_closed(boundary)], colors=[_GREY], radii=[0.02]),
        static=True,
    )
    rec.log(
        "world/arena/target/T1",
        rr.LineStrips3D([_closed(scenario.target.shape.vertices())], colors=[_GREEN], radii=[0.02]),
        static=True,
    )
    rec.log(
        "world/arena/target/T2",
        rr.LineStrips3D(
            [_closed(scenario.abstract_target().vertices())], colors=[_GREEN], radii=[0.008]
        ),
        static=True,
    )
    return 3


def log_obstacles(rec: rr.RecordingStream, run: RunData, scenario: Scenario | None) -> int:
    """Log the real and inflated obstacles, one row per recorded layout (they may move)."""
    if not run.layouts:
        return 0
    t_ns = [layout.t_ns for layout in run.layouts]
    real = [[_closed(p) for p in layout.real] for layout in run.layouts]
    rows = _strip_rows(rec, "world/arena/obstacles/real", t_ns, real)
    if scenario is not None or all(layout.inflated for layout in run.layouts):
        inflated = [
            [
                _closed(p)
                for p in (
                    layout.inflated if scenario is None else inflated_outlines(scenario, layout)
                )
            ]
            for layout in run.layouts
        ]
        rows += _strip_rows(rec, "world/arena/obstacles/inflated", t_ns, inflated)
    return rows


# ---------------------------------------------------------------- the vessel


def _hull_outline(length_m: float, beam_m: float) -> FloatArray:
    """Return the hull outline in the body frame with a pointed bow, shape (6, 3)."""
    half_l, half_b = 0.5 * length_m, 0.5 * beam_m
    bow = half_l - half_b
    xy = np.array(
        [[-half_l, -half_b], [bow, -half_b], [half_l, 0.0], [bow, half_b], [-half_l, half_b]]
    )
    return _closed(xy)


def log_hull(rec: rr.RecordingStream, scenario: Scenario | None) -> int:
    """Log the hull outline in the body frame (static; default hull without a scenario)."""
    hull = scenario.hull if scenario is not None else Hull()
    rec.log(
        "world/vessel/hull",
        rr.LineStrips3D([_hull_outline(hull.length_m, hull.beam_m)], colors=[_BLUE], radii=[0.012]),
        static=True,
    )
    return 1


def _quaternion_z(yaw_rad: FloatArray) -> FloatArray:
    """Return rotations about z as quaternions (x, y, z, w), shape (N, 4), for yaw (N,)."""
    half = 0.5 * np.asarray(yaw_rad, dtype=np.float64)
    zeros = np.zeros(len(half))
    out: FloatArray = np.column_stack([zeros, zeros, np.sin(half), np.cos(half)])
    return out


def log_vessel(rec: rr.RecordingStream, run: RunData, scenario: Scenario | None) -> int:
    """Log the body frame at every measured pose and the hull outline in it.

    One transform row per pose sample (the estimate when the log has no pose).
    """
    rows = log_hull(rec, scenario)
    series = run.pose if len(run.pose) else run.estimate
    translation = np.column_stack([series.values[:, :2], np.zeros(len(series))])
    rec.send_columns(
        "world/vessel",
        indexes=[_time(series.t_ns)],
        columns=rr.Transform3D.columns(
            translation=translation, quaternion=_quaternion_z(series.values[:, 2])
        ),
    )
    return rows + len(series)


def log_pose_samples(rec: rr.RecordingStream, run: RunData) -> int:
    """Log each measured pose as a point in the arena, one row per sample."""
    if not len(run.pose):
        return 0
    positions = np.column_stack([run.pose.values[:, :2], np.zeros(len(run.pose))])
    rec.send_columns(
        "world/pose_samples",
        indexes=[_time(run.pose.t_ns)],
        columns=rr.Points3D.columns(positions=positions),
    )
    return len(run.pose)


def log_trajectory(rec: rr.RecordingStream, run: RunData) -> int:
    """Log the estimated path of the whole run as one static line strip."""
    if not len(run.estimate):
        return 0
    path = np.column_stack([run.estimate.values[:, :2], np.zeros(len(run.estimate))])
    rec.log("world/trajectory", rr.LineStrips3D([path], colors=[_BLUE], radii=[0.006]), static=True)
    return 1


# ---------------------------------------------------------------- the controller's view


def _decision_strips(decision: Decision, tau_s: float) -> tuple[list[FloatArray], list[FloatArray]]:
    """Return the arcs of the safe inputs and of the chosen input (none if none), each (n, 3)."""
    arcs = predicted_arcs(decision.state, decision.safe_inputs_array(), tau_s, _ARC_POINTS)
    safe = [np.column_stack([a, np.full(len(a), _Z_ARCS)]) for a in arcs]
    if decision.chosen_index < 0:
        return safe, []
    arc = predicted_arcs(decision.state, np.array([decision.chosen_input]), tau_s, _ARC_POINTS)[0]
    return safe, [np.column_stack([arc, np.full(len(arc), 2 * _Z_ARCS)])]


def log_decisions(rec: rr.RecordingStream, run: RunData, tau_s: float) -> int:
    """Log the safe inputs as predicted arcs over tau and the chosen one, per decision."""
    if not run.decisions:
        return 0
    t_ns = [d.t_ns for d in run.decisions]
    strips = [_decision_strips(d, tau_s) for d in run.decisions]
    rows = _strip_rows(rec, "world/controller/safe_inputs", t_ns, [s for s, _ in strips])
    rows += _strip_rows(rec, "world/controller/chosen_input", t_ns, [c for _, c in strips])
    return rows


def decisions_differ(recorded: Decision, replayed: Decision) -> bool:
    """Return True when a replayed decision has another safe-input set or chosen input."""
    return (
        set(recorded.safe_input_indices) != set(replayed.safe_input_indices)
        or recorded.chosen_index != replayed.chosen_index
    )


def log_replayed_decisions(
    rec: rr.RecordingStream,
    recorded: Sequence[Decision],
    replayed: Sequence[Decision],
    tau_s: float,
) -> int:
    """Log replayed decisions beside the recorded ones and mark where they differ.

    Decision i of `replayed` is compared with decision i of `recorded`; the
    replayed arcs go to ``world/replay/...``, each differing decision gets a
    marker at its state (``world/replay/differs``), a 1 on ``plots/replay/differs``
    and a warning on ``events/replay``.

    Returns:
        The number of rows sent.
    """
    if not replayed:
        return 0
    t_ns = [d.t_ns for d in replayed]
    strips = [_decision_strips(d, tau_s) for d in replayed]
    rows = _strip_rows(rec, "world/replay/safe_inputs", t_ns, [s for s, _ in strips])
    rows += _strip_rows(rec, "world/replay/chosen_input", t_ns, [c for _, c in strips])
    pairs = list(zip(recorded, replayed, strict=False))
    differs = [decisions_differ(a, b) for a, b in pairs]
    if len(replayed) != len(recorded):
        differs.extend([True] * (len(replayed) - len(pairs)))
    marks = np.array(differs, dtype=np.float64)[:, None]
    rows += _scalars(rec, "plots/replay/differs", Series(np.asarray(t_ns, dtype=np.int64), marks))
    where = [i for i, bad in enumerate(differs) if bad]
    if where:
        rec.send_columns(
            "world/replay/differs",
            indexes=[_time(np.array([t_ns[i] for i in where], dtype=np.int64))],
            columns=rr.Points3D.columns(positions=[[*replayed[i].state[:2], 0.05] for i in where]),
        )
        text = [
            f"decision {i} at t={t_ns[i] / 1e9:.2f} s differs: replayed chosen "
            f"{replayed[i].chosen_index}, {len(replayed[i].safe_inputs)} safe; recorded "
            + (
                f"chosen {recorded[i].chosen_index}, {len(recorded[i].safe_inputs)} safe"
                if i < len(recorded)
                else "none"
            )
            for i in where
        ]
        rec.send_columns(
            "events/replay",
            indexes=[_time(np.array([t_ns[i] for i in where], dtype=np.int64))],
            columns=rr.TextLog.columns(text=text, level=["WARN"] * len(where)),
        )
        rows += 2 * len(where)
    return rows


def _slice_rgba(slice_: WinningSlice) -> NDArray[np.uint8]:
    """Color a V slice: winning cells green (darker = closer), obstacles grey, rest clear.

    Returns:
        RGBA pixels, shape (ny, nx, 4): pixel [r, i] is cell (i, ny - 1 - r). The
        viewer puts the first row at the top (largest y) of the grid map.
    """
    values = slice_.values.T[::-1]  # (ny, nx), y descending
    obstacles = slice_.obstacles.T[::-1]
    rgba = np.zeros((*values.shape, 4), dtype=np.uint8)
    winning = values >= 0
    top = max(int(values.max(initial=0)), 1)
    shade = (values / top).clip(0.0, 1.0)
    rgba[..., 0] = np.where(winning, 30 + 120 * shade, 0).astype(np.uint8)
    rgba[..., 1] = np.where(winning, 120 + 110 * shade, 0).astype(np.uint8)
    rgba[..., 2] = np.where(winning, 60 + 80 * shade, 0).astype(np.uint8)
    rgba[..., 3] = np.where(winning, 150, 0).astype(np.uint8)
    rgba[obstacles] = (90, 90, 90, 150)
    return rgba


def _grid_map_pixels(slice_: WinningSlice | None) -> tuple[NDArray[np.uint8], float, list[float]]:
    """Return the RGBA pixels (h, w, 4), the square pixel size (m) and the lower-left corner."""
    if slice_ is None:  # one clear pixel: nothing to show at this decision
        return np.zeros((1, 1, 4), dtype=np.uint8), 0.01, [0.0, 0.0, _Z_GRID]
    grid = slice_.grid
    rgba = _slice_rgba(slice_)
    cell_m = min(grid.cell_x_m, grid.cell_y_m)
    # Non-square cells: repeat pixels so that each grid-map pixel is square.
    rx = max(round(grid.cell_x_m / cell_m), 1)
    ry = max(round(grid.cell_y_m / cell_m), 1)
    rgba = np.ascontiguousarray(rgba.repeat(ry, axis=0).repeat(rx, axis=1))
    return rgba, cell_m, [grid.x_min_m, grid.y_min_m, _Z_GRID]


def log_winning_set(rec: rr.RecordingStream, run: RunData, view: ControllerView) -> int:
    """Log the winning set's slice at each decision's heading cell as a grid map.

    One row per decision; a decision without a slice gets one clear pixel.
    """
    if not run.decisions:
        return 0
    pixels = [_grid_map_pixels(s) for s in view.slices]
    formats = [
        rr.components.ImageFormat(
            width=p.shape[1], height=p.shape[0], color_model="RGBA", channel_datatype="U8"
        )
        for p, _, _ in pixels
    ]
    t_ns = np.array([d.t_ns for d in run.decisions], dtype=np.int64)
    rec.send_columns(
        "world/controller/winning_set",
        indexes=[_time(t_ns)],
        columns=[
            *rr.GridMap.columns(
                data=[p.tobytes() for p, _, _ in pixels],
                format=formats,
                cell_size=[c for _, c, _ in pixels],
                translation=[t for _, _, t in pixels],
            ),
            *rr.AnyValues.columns(
                heading_cell=[-1 if s is None else s.heading_cell for s in view.slices],
                winning_cells=[0 if s is None else s.winning_cells for s in view.slices],
            ),
        ],
    )
    return len(run.decisions)


# ---------------------------------------------------------------- time series


def log_velocity(rec: rr.RecordingStream, run: RunData) -> int:
    """Log commanded (nu_ref) and estimated (nu_hat) velocity per axis."""
    rows = 0
    estimate_nu = Series(run.estimate.t_ns, run.estimate.values[:, 3:6])
    for k, (axis, _) in enumerate(_AXES):
        rows += _scalars(rec, f"plots/velocity/{axis}/commanded", run.reference, [k])
        rows += _scalars(rec, f"plots/velocity/{axis}/estimated", estimate_nu, [k])
    return rows


def tracking_error(run: RunData) -> Series:
    """Return nu_hat - nu_ref at each estimate, the reference held since it was issued.

    Returns:
        Values shape (N, 3): surge, sway, yaw-rate error (m/s, m/s, rad/s), at the
        estimates issued at or after the first reference.
    """
    if not len(run.reference) or not len(run.estimate):
        return Series.empty(3)
    idx = np.searchsorted(run.reference.t_ns, run.estimate.t_ns, side="right") - 1
    keep = idx >= 0
    error = run.estimate.values[keep, 3:6] - run.reference.values[idx[keep]]
    return Series(run.estimate.t_ns[keep], error)


def _margin_band(t_ns: NDArray[np.int64], margin: FloatArray, k: int) -> Series:
    """Return the band +-margin[k] at the times `t_ns` (first and last suffice)."""
    return Series(t_ns, np.tile([margin[k], -margin[k]], (len(t_ns), 1)))


def log_tracking_error(rec: rr.RecordingStream, run: RunData, margin: FloatArray | None) -> int:
    """Log the tracking error per axis with the scenario's margin band (+-margin)."""
    error = tracking_error(run)
    if not len(error):
        return 0
    rows = 0
    for k, (axis, _) in enumerate(_AXES):
        rows += _scalars(rec, f"plots/tracking_error/{axis}/error", error, [k])
        if margin is not None:
            band = _margin_band(error.t_ns[[0, -1]], margin, k)
            rows += _scalars(rec, f"plots/tracking_error/{axis}/margin", band)
    return rows


def log_thrusters(rec: rr.RecordingStream, run: RunData) -> int:
    """Log the normalized thruster commands and the azimuth angles (deg)."""
    rows = _scalars(rec, "plots/thrusters/commands", run.thrusters, [0, 1, 2])
    rows += _scalars(
        rec, "plots/thrusters/azimuth_deg", run.thrusters, [3, 4], scale=180.0 / math.pi
    )
    return rows


def log_force(rec: rr.RecordingStream, run: RunData) -> int:
    """Log the generalized force demand tau (X N, Y N, N N m)."""
    return _scalars(rec, "plots/force", run.force)


def _finite_or_nan(value: float) -> float:
    return value if math.isfinite(value) else math.nan


def log_value(rec: rr.RecordingStream, run: RunData) -> int:
    """Log the value function (steps to the target) at each decision; NaN when not winning."""
    if not run.decisions:
        return 0
    t_ns = np.array([d.t_ns for d in run.decisions], dtype=np.int64)
    value = np.array([_finite_or_nan(d.value) for d in run.decisions])
    return _scalars(rec, "plots/value", Series(t_ns, value[:, None]))


def log_synthesis_time(rec: rr.RecordingStream, run: RunData) -> int:
    """Log the wall time of each re-synthesis (s)."""
    times = run.synthesis_times()
    if not times:
        return 0
    series = Series(
        np.array([s.t_ns for s in times], dtype=np.int64), np.array([[s.seconds] for s in times])
    )
    return _scalars(rec, "plots/synthesis_time_s", series)


def log_events(rec: rr.RecordingStream, run: RunData) -> int:
    """Log events and faults as text log entries with their level."""
    if not run.events:
        return 0
    t_ns = np.array([e.t_ns for e in run.events], dtype=np.int64)
    text = [f"{e.code}: {e.text}" for e in run.events]
    levels = [_LEVELS.get(e.level, "INFO") for e in run.events]
    rec.send_columns(
        "events", indexes=[_time(t_ns)], columns=rr.TextLog.columns(text=text, level=levels)
    )
    return len(run.events)


# ---------------------------------------------------------------- layout and entry points


def blueprint(scenario: Scenario | None = None, *, replay: bool = False) -> rrb.Blueprint:
    """Return the viewer layout: the arena top-down beside the time series.

    With `replay`, a tab shows where the replayed decisions differ.
    """
    if scenario is not None:
        cx = 0.5 * sum(scenario.x_range_m)
        cy = 0.5 * sum(scenario.y_range_m)
        height = 1.1 * max(
            scenario.x_range_m[1] - scenario.x_range_m[0],
            scenario.y_range_m[1] - scenario.y_range_m[0],
        )
    else:
        cx, cy, height = 0.0, 0.0, 10.0
    arena = rrb.Spatial3DView(
        name="arena (top-down, x right, y up)",
        origin="/world",
        eye_controls=rrb.EyeControls3D(
            position=[cx, cy, height], look_target=[cx, cy, 0.0], eye_up=[0.0, 1.0, 0.0]
        ),
        line_grid=False,
    )
    velocity = rrb.Vertical(
        *(
            rrb.TimeSeriesView(name=f"velocity {label}", origin=f"/plots/velocity/{axis}")
            for axis, label in _AXES
        ),
        name="velocity",
    )
    error = rrb.Vertical(
        *(
            rrb.TimeSeriesView(
                name=f"tracking error {label}", origin=f"/plots/tracking_error/{axis}"
            )
            for axis, label in _AXES
        ),
        name="tracking error",
    )
    actuators = rrb.Vertical(
        rrb.TimeSeriesView(name="thruster commands", origin="/plots/thrusters/commands"),
        rrb.TimeSeriesView(name="azimuth angles (deg)", origin="/plots/thrusters/azimuth_deg"),
        rrb.TimeSeriesView(name="force demand", origin="/plots/force"),
        name="actuators",
    )
    controller = rrb.Vertical(
        rrb.TimeSeriesView(name="value V (steps)", origin="/plots/value"),
        rrb.TimeSeriesView(name="synthesis time (s)", origin="/plots/synthesis_time_s"),
        name="controller",
    )
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                arena, rrb.TextLogView(name="events", origin="/events"), row_shares=[4, 1]
            ),
            rrb.Tabs(velocity, error, actuators, controller, *_replay_tab(replay)),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(timeline=TIMELINE),
        collapse_panels=False,
    )


def _replay_tab(replay: bool) -> list[rrb.Vertical]:
    if not replay:
        return []
    return [
        rrb.Vertical(
            rrb.TimeSeriesView(name="replay differs (1 = yes)", origin="/plots/replay"),
            rrb.TextLogView(name="replay differences", origin="/events/replay"),
            name="replay",
        )
    ]


def log_run(
    rec: rr.RecordingStream,
    run: RunData,
    scenario: Scenario | None,
    view: ControllerView | None,
    replayed: Sequence[Decision] | None = None,
) -> int:
    """Log every stream of `run` (and `replayed` decisions beside) to `rec`; return the rows."""
    tau_s = scenario.tau_s if scenario is not None else 2.0
    margin = scenario.margin.as_array() if scenario is not None else None
    rows = log_styles(rec)
    rows += log_arena(rec, scenario)
    rows += log_obstacles(rec, run, scenario)
    rows += log_vessel(rec, run, scenario)
    rows += log_pose_samples(rec, run)
    rows += log_trajectory(rec, run)
    rows += log_decisions(rec, run, tau_s)
    if view is not None:
        rows += log_winning_set(rec, run, view)
    rows += log_velocity(rec, run)
    rows += log_tracking_error(rec, run, margin)
    rows += log_thrusters(rec, run)
    rows += log_force(rec, run)
    rows += log_value(rec, run)
    rows += log_synthesis_time(rec, run)
    rows += log_events(rec, run)
    if replayed is not None:
        rows += log_replayed_decisions(rec, run.decisions, replayed, tau_s)
    return rows


def _recording(run: RunData) -> rr.RecordingStream:
    name = run.path.name or str(run.path)
    return rr.RecordingStream(
        APPLICATION_ID, recording_id=f"{name}-{run.start_ns}-{run.end_ns}", send_properties=False
    )


def write_rrd(
    run: RunData,
    path: str | Path,
    scenario: Scenario | None,
    view: ControllerView | None,
    replayed: Sequence[Decision] | None = None,
) -> ExportStats:
    """Write the run to an ``.rrd`` file with its blueprint.

    Args:
        run: The recorded run.
        path: The ``.rrd`` file to write (replaced if it exists).
        scenario: The run's scenario (arena, hull, tau, margin); None when unknown.
        view: The controller's view per decision; None to leave out the winning set.
        replayed: Decisions of a replay of the run, shown beside the recorded ones
            with their differences marked (``hil replay LOG --rerun``); None for none.

    Returns:
        What was written.

    Raises:
        RrdWriteError: The file cannot be created.
    """
    start = time.perf_counter()
    out = Path(path)
    if not out.parent.is_dir():
        raise RrdWriteError(f"cannot write {str(out)!r}: {str(out.parent)!r} is not a folder")
    rec = _recording(run)
    try:
        rec.save(out, default_blueprint=blueprint(scenario, replay=replayed is not None))
    except RuntimeError as err:
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise RrdWriteError(f"cannot write {str(out)!r}: {first}") from err
    rows = log_run(rec, run, scenario, view, replayed)
    rec.flush()
    rec.disconnect()
    return ExportStats(out, out.stat().st_size, rows, time.perf_counter() - start)


class ViewerError(RuntimeError):
    """The Rerun viewer cannot be started."""


class RrdWriteError(OSError):
    """An ``.rrd`` file cannot be written (its message names the path)."""


def _spawn(rec: rr.RecordingStream, scenario: Scenario | None) -> None:
    """Start a viewer and connect `rec` to it.

    Raises:
        ViewerError: The viewer executable is missing or does not start.
    """
    # An un-activated virtual environment has the viewer beside its python, not on PATH.
    beside = Path(sys.executable).with_name("rerun")
    if shutil.which("rerun") is None and beside.is_file():
        os.environ["PATH"] = f"{beside.parent}{os.pathsep}{os.environ.get('PATH', '')}"
    try:
        rec.spawn(default_blueprint=blueprint(scenario))
    except RuntimeError as err:
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise ViewerError(f"cannot start the Rerun viewer: {first}") from err


def spawn_viewer(
    run: RunData, scenario: Scenario | None, view: ControllerView | None
) -> ExportStats:
    """Open the Rerun viewer and stream the run to it.

    Raises:
        ViewerError: The viewer cannot be started.
    """
    start = time.perf_counter()
    rec = _recording(run)
    _spawn(rec, scenario)
    rows = log_run(rec, run, scenario, view)
    try:
        rec.flush(timeout_sec=30.0)
    except RuntimeError as err:
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise ViewerError(f"the Rerun viewer did not take the run: {first}") from err
    return ExportStats(None, 0, rows, time.perf_counter() - start)


# ---------------------------------------------------------------- live (hil run --rerun)


class LiveRerunLog:
    """A RunLog that streams every record to Rerun while the run goes on.

    Uses the entity paths and blueprint of the post-run export, row by row
    (``rr.log`` at the record's time), and forwards every call to `inner` (the
    recorder, say) first, so a live view never costs the recorded data. The
    winning set is not shown live (the runtime's controller is not a record).

    Args:
        rec: The recording stream (already spawned, connected or saving).
        scenario: The run's scenario (arena, hull, tau, margin, inflation).
        inner: The log to forward to; None for none.
    """

    def __init__(
        self, rec: rr.RecordingStream, scenario: Scenario, inner: RunLog | None = None
    ) -> None:
        self.rec = rec
        self.scenario = scenario
        self.inner = inner
        self._margin = scenario.margin.as_array()
        self._nu_ref: FloatArray | None = None
        log_styles(rec)
        log_arena(rec, scenario)
        log_hull(rec, scenario)

    @staticmethod
    def open(
        scenario: Scenario,
        *,
        spawn: bool = False,
        save: Path | None = None,
        inner: RunLog | None = None,
        recording_id: str | None = None,
    ) -> LiveRerunLog:
        """Return a live log that spawns a viewer and/or saves to `save` (an .rrd file)."""
        rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id, send_properties=False)
        if spawn:
            _spawn(rec, scenario)
        if save is not None:
            # Save beside the viewer: set_sinks replaces the sinks, so name both.
            sinks: list[rr.FileSink | rr.GrpcSink] = [rr.FileSink(str(save))]
            if spawn:
                sinks.append(rr.GrpcSink())
            rec.set_sinks(*sinks, default_blueprint=blueprint(scenario))
        return LiveRerunLog(rec, scenario, inner)

    def _at(self, t_ns: int) -> None:
        self.rec.set_time(TIMELINE, duration=np.timedelta64(int(t_ns), "ns"))

    def pose(self, sample: PoseSample) -> None:
        """Move the body frame and add a pose point."""
        if self.inner is not None:
            self.inner.pose(sample)
        self._at(sample.t_ns)
        position = [sample.x_m, sample.y_m, 0.0]
        quaternion = _quaternion_z(np.array([sample.yaw_rad]))[0]
        self.rec.log("world/vessel", rr.Transform3D(translation=position, quaternion=quaternion))
        self.rec.log("world/pose_samples", rr.Points3D([position]))

    def imu(self, sample: ImuSample) -> None:
        """Forward only: the IMU is not drawn."""
        if self.inner is not None:
            self.inner.imu(sample)

    def estimate(self, t_ns: int, eta: FloatArray, nu: FloatArray) -> None:
        """Plot the estimated velocity and, against the last reference, the tracking error."""
        if self.inner is not None:
            self.inner.estimate(t_ns, eta, nu)
        self._at(t_ns)
        for k, (axis, _) in enumerate(_AXES):
            self.rec.log(f"plots/velocity/{axis}/estimated", rr.Scalars(float(nu[k])))
            if self._nu_ref is not None:
                error = float(nu[k] - self._nu_ref[k])
                self.rec.log(f"plots/tracking_error/{axis}/error", rr.Scalars(error))
                band = [float(self._margin[k]), -float(self._margin[k])]
                self.rec.log(f"plots/tracking_error/{axis}/margin", rr.Scalars(band))

    def velocity_reference(self, t_ns: int, nu_ref: FloatArray) -> None:
        """Plot the commanded velocity."""
        if self.inner is not None:
            self.inner.velocity_reference(t_ns, nu_ref)
        self._nu_ref = np.array(nu_ref, dtype=np.float64)
        self._at(t_ns)
        for k, (axis, _) in enumerate(_AXES):
            self.rec.log(f"plots/velocity/{axis}/commanded", rr.Scalars(float(nu_ref[k])))

    def force(self, t_ns: int, tau: FloatArray) -> None:
        """Plot the force demand."""
        if self.inner is not None:
            self.inner.force(t_ns, tau)
        self._at(t_ns)
        self.rec.log("plots/force", rr.Scalars(np.asarray(tau, dtype=np.float64)))

    def thrusters(self, command: ThrusterCommand) -> None:
        """Plot the thruster commands and azimuth angles."""
        if self.inner is not None:
            self.inner.thrusters(command)
        self._at(command.t_ns)
        self.rec.log(
            "plots/thrusters/commands",
            rr.Scalars([command.tunnel, command.port, command.starboard]),
        )
        angles = np.degrees([command.port_angle_rad, command.starboard_angle_rad])
        self.rec.log("plots/thrusters/azimuth_deg", rr.Scalars(angles))

    def decision(self, record: Decision) -> None:
        """Draw the safe inputs and the chosen one as arcs; plot the value."""
        if self.inner is not None:
            self.inner.decision(record)
        self._at(record.t_ns)
        safe, chosen = _decision_strips(record, self.scenario.tau_s)
        self.rec.log("world/controller/safe_inputs", rr.LineStrips3D(safe))
        self.rec.log("world/controller/chosen_input", rr.LineStrips3D(chosen))
        self.rec.log("plots/value", rr.Scalars(_finite_or_nan(record.value)))

    def obstacles(self, layout: ObstacleLayout) -> None:
        """Draw the real and inflated obstacles of a new layout."""
        if self.inner is not None:
            self.inner.obstacles(layout)
        self._at(layout.t_ns)
        real = tuple(
            _rect((r.x_min_m, r.x_max_m), (r.y_min_m, r.y_max_m)) for r in layout.obstacles
        )
        drawn = Layout(layout.t_ns, real, (), layout.obstacles)
        self.rec.log("world/arena/obstacles/real", rr.LineStrips3D([_closed(p) for p in real]))
        inflated = inflated_outlines(self.scenario, drawn)
        self.rec.log(
            "world/arena/obstacles/inflated", rr.LineStrips3D([_closed(p) for p in inflated])
        )

    def event(self, t_ns: int, level: EventLevel, code: str, text: str) -> None:
        """Add a text log entry; plot the synthesis time of a new controller."""
        if self.inner is not None:
            self.inner.event(t_ns, level, code, text)
        self._at(t_ns)
        self.rec.log("events", rr.TextLog(f"{code}: {text}", level=_LEVELS.get(level, "INFO")))
        timing = synthesis_time(Event(t_ns, level, code, text))
        if timing is not None:
            self.rec.log("plots/synthesis_time_s", rr.Scalars(timing.seconds))

    def close(self) -> None:
        """Flush what is buffered and detach from the sinks."""
        self.rec.flush()
        self.rec.disconnect()
