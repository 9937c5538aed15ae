"""The arena-frame entities of a recorded run: ``world/...`` in Rerun.

The arena (static), the obstacles per layout, the body frame at each pose with
the hull, the measured and estimated paths, the controller's view per decision
(safe and chosen inputs as predicted arcs, the winning set as a grid map), and a
replay's decisions beside the recorded ones.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import rerun as rr
from numpy.typing import NDArray

from hil.bag.run_data import RunData, Series
from hil.core.arrays import FloatArray
from hil.core.geometry import yaw_quaternions
from hil.core.records import Decision
from hil.scenarios import Hull, Scenario
from hil.views.controller_view import (
    ControllerView,
    WinningSlice,
    inflated_outlines,
    obstacle_names,
)
from hil.views.rerun_style import (
    BLUE,
    GREEN,
    GREY,
    RED,
    WORLD_COORDINATES,
    closed_strip,
    decision_strips,
    rectangle_xy,
    send_scalars,
    send_strips,
    time_column,
)

_Z_GRID = 0.02  # z is down: the winning set lies just under the arena lines
_Z_MARK = -0.05  # z is down: replay markers float above the arcs
_AXIS_M = 1.0  # length of the drawn x (north) and y (east) arrows (m)


def log_arena(rec: rr.RecordingStream, scenario: Scenario | None) -> int:
    """Log the frame, the boundary, the axes and the targets T1 (real) and T2 (abstract), static.

    The arena frame is NED-like: x north, y east, z down (``RIGHT_HAND_Z_DOWN``); the
    blueprint looks at it from above (:func:`hil.views.blueprint.top_down_eye`).
    Without a scenario (an unknown one) only the frame is logged.
    """
    rec.log("world", WORLD_COORDINATES, static=True)
    if scenario is None:
        return 1
    corner = [scenario.x_range_m[0], scenario.y_range_m[0], 0.0]
    rec.log(
        "world/arena/axes",
        rr.Arrows3D(
            origins=[corner, corner],
            vectors=[[_AXIS_M, 0.0, 0.0], [0.0, _AXIS_M, 0.0]],
            labels=["x north", "y east"],
            colors=[RED, GREEN],
            show_labels=True,
        ),
        static=True,
    )
    boundary = rectangle_xy(scenario.x_range_m, scenario.y_range_m)
    rec.log(
        "world/arena/boundary",
        rr.LineStrips3D([closed_strip(boundary)], colors=[GREY], radii=[0.02]),
        static=True,
    )
    rec.log(
        "world/arena/target/T1",
        rr.LineStrips3D(
            [closed_strip(scenario.target.shape.vertices())],
            colors=[GREEN],
            radii=[0.02],
            labels=["T1"],
            show_labels=True,
        ),
        static=True,
    )
    rec.log(
        "world/arena/target/T2",
        rr.LineStrips3D(
            [closed_strip(scenario.abstract_target().vertices())], colors=[GREEN], radii=[0.008]
        ),
        static=True,
    )
    return 5


def log_obstacles(rec: rr.RecordingStream, run: RunData, scenario: Scenario | None) -> int:
    """Log the real and inflated obstacles, one row per recorded layout (they may move)."""
    if not run.layouts:
        return 0
    t_ns = [layout.t_ns for layout in run.layouts]
    real = [[closed_strip(p) for p in layout.real] for layout in run.layouts]
    rows = send_strips(rec, "world/arena/obstacles/real", t_ns, real)
    if scenario is not None or all(layout.inflated for layout in run.layouts):
        inflated = [
            [
                closed_strip(p)
                for p in (
                    layout.inflated if scenario is None else inflated_outlines(scenario, layout)
                )
            ]
            for layout in run.layouts
        ]
        rows += send_strips(rec, "world/arena/obstacles/inflated", t_ns, inflated)
    return rows + _log_obstacle_names(rec, run, scenario)


def _log_obstacle_names(rec: rr.RecordingStream, run: RunData, scenario: Scenario | None) -> int:
    """Name each layout's obstacles at their centres (the scenario's names, else O1, ...)."""
    centres = [[[*np.asarray(p).mean(axis=0), 0.0] for p in layout.real] for layout in run.layouts]
    names = [obstacle_names(scenario, len(layout.real)) for layout in run.layouts]
    rec.send_columns(
        "world/arena/obstacles/names",
        indexes=[time_column(np.array([layout.t_ns for layout in run.layouts], dtype=np.int64))],
        columns=rr.Points3D.columns(
            positions=[c for row in centres for c in row],
            labels=[n for row in names for n in row],
        ).partition([len(row) for row in centres]),
    )
    return len(run.layouts)


# ---------------------------------------------------------------- the vessel


def _hull_outline(length_m: float, beam_m: float) -> FloatArray:
    """Return the hull outline in the body frame with a pointed bow, shape (6, 3)."""
    half_l, half_b = 0.5 * length_m, 0.5 * beam_m
    bow = half_l - half_b
    xy = np.array(
        [[-half_l, -half_b], [bow, -half_b], [half_l, 0.0], [bow, half_b], [-half_l, half_b]]
    )
    return closed_strip(xy)


def log_hull(rec: rr.RecordingStream, scenario: Scenario | None) -> int:
    """Log the hull outline in the body frame (static; default hull without a scenario)."""
    hull = scenario.hull if scenario is not None else Hull()
    rec.log(
        "world/vessel/hull",
        rr.LineStrips3D([_hull_outline(hull.length_m, hull.beam_m)], colors=[BLUE], radii=[0.012]),
        static=True,
    )
    return 1


def log_vessel(rec: rr.RecordingStream, run: RunData, scenario: Scenario | None) -> int:
    """Log the body frame at every measured pose and the hull outline in it.

    One transform row per pose sample (the estimate when the log has no pose).
    """
    rows = log_hull(rec, scenario)
    series = run.pose if len(run.pose) else run.estimate
    translation = np.column_stack([series.values[:, :2], np.zeros(len(series))])
    rec.send_columns(
        "world/vessel",
        indexes=[time_column(series.t_ns)],
        columns=rr.Transform3D.columns(
            translation=translation, quaternion=yaw_quaternions(series.values[:, 2])
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
        indexes=[time_column(run.pose.t_ns)],
        columns=rr.Points3D.columns(positions=positions),
    )
    return len(run.pose)


def log_trajectory(rec: rr.RecordingStream, run: RunData) -> int:
    """Log the estimated path of the whole run as one static line strip."""
    if not len(run.estimate):
        return 0
    path = np.column_stack([run.estimate.values[:, :2], np.zeros(len(run.estimate))])
    rec.log("world/trajectory", rr.LineStrips3D([path], colors=[BLUE], radii=[0.006]), static=True)
    rec.log(
        "world/trajectory/ends",
        rr.Points3D(
            [path[0], path[-1]],
            labels=["start", "end"],
            colors=[BLUE],
            radii=[0.05],
            show_labels=True,
        ),
        static=True,
    )
    return 2


def log_decisions(rec: rr.RecordingStream, run: RunData, tau_s: float) -> int:
    """Log the safe inputs as predicted arcs over tau and the chosen one, per decision."""
    if not run.decisions:
        return 0
    t_ns = [d.t_ns for d in run.decisions]
    strips = [decision_strips(d, tau_s) for d in run.decisions]
    rows = send_strips(rec, "world/controller/safe_inputs", t_ns, [s for s, _ in strips])
    rows += send_strips(rec, "world/controller/chosen_input", t_ns, [c for _, c in strips])
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
    strips = [decision_strips(d, tau_s) for d in replayed]
    rows = send_strips(rec, "world/replay/safe_inputs", t_ns, [s for s, _ in strips])
    rows += send_strips(rec, "world/replay/chosen_input", t_ns, [c for _, c in strips])
    pairs = list(zip(recorded, replayed, strict=False))
    differs = [decisions_differ(a, b) for a, b in pairs]
    if len(replayed) != len(recorded):
        differs.extend([True] * (len(replayed) - len(pairs)))
    marks = np.array(differs, dtype=np.float64)[:, None]
    rows += send_scalars(
        rec, "plots/replay/differs", Series(np.asarray(t_ns, dtype=np.int64), marks)
    )
    where = [i for i, bad in enumerate(differs) if bad]
    if where:
        rec.send_columns(
            "world/replay/differs",
            indexes=[time_column(np.array([t_ns[i] for i in where], dtype=np.int64))],
            columns=rr.Points3D.columns(
                positions=[[*replayed[i].state[:2], _Z_MARK] for i in where]
            ),
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
            indexes=[time_column(np.array([t_ns[i] for i in where], dtype=np.int64))],
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
        indexes=[time_column(t_ns)],
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
