"""A one-page picture of a recorded run, like the paper's Fig. 6-8 (matplotlib, Agg).

Left: the arena as the tank is seen from above, with the boundary, the real
obstacles (filled, named as in the scenario) and the inflated ones (dashed), the
target T1 and the abstract target T2, the estimated trajectory from its start to its
end, and the hull outline every few seconds. The arena frame is NED-like (x north,
y east, z down), so seen from above x points right and y points DOWN the page
(:func:`orient_from_above`); a starboard turn (r > 0) is drawn clockwise. The paper
draws x right, y up: the tank seen from below.
Right: velocity tracking per axis, commanded (nu_ref) against estimated (nu_hat),
with yaw rate in deg/s as the paper reports it, and the RMS of the tracking
error of :mod:`hil.core.tracking` (the figure replay judges) above each axis.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Polygon as PolygonPatch
from numpy.typing import NDArray

from hil.bag.run_data import RunData
from hil.core.arrays import FloatArray
from hil.core.tracking import for_display
from hil.scenarios import Hull, Scenario, hull_footprint
from hil.views.controller_view import inflated_outlines, obstacle_names

FIGURE_SIZE_IN = (13.0, 6.5)
"""Figure size (width, height) in inches; the PNG is this times the dpi, in pixels."""
DEFAULT_DPI = 110
HULL_EVERY_S = 5.0
"""Default time between two hull outlines (s)."""

_AXES = (
    ("surge u (m/s)", 1.0),
    ("sway v (m/s)", 1.0),
    ("yaw rate r (deg/s)", 180.0 / math.pi),
)


def _closed(xy: FloatArray) -> tuple[FloatArray, FloatArray]:
    ring = np.vstack([xy, xy[:1]])
    return ring[:, 0], ring[:, 1]


def _hull_times(t_ns: NDArray[np.int64], every_s: float) -> NDArray[np.intp]:
    """Return the indices of the samples nearest to every `every_s` seconds, and the last."""
    if not len(t_ns):
        return np.zeros(0, dtype=np.intp)
    marks = np.arange(t_ns[0], t_ns[-1], max(every_s, 1e-3) * 1e9)
    idx = np.unique(np.append(np.searchsorted(t_ns, marks), len(t_ns) - 1))
    return np.asarray(np.clip(idx, 0, len(t_ns) - 1), dtype=np.intp)


ARENA_TITLE = "arena seen from above (x north, y east, z down into the page)"
"""The arena panel's title: the frame and where it is seen from."""


def orient_from_above(
    ax: Axes, x_range_m: tuple[float, float], y_range_m: tuple[float, float]
) -> None:
    """Show the arena frame (x north, y east, z down) on `ax` as seen from above.

    x (north) runs to the right and y (east) DOWN the page: with z down into the page
    the frame stays right-handed on paper, so a heading increasing (a starboard turn,
    r > 0) is drawn clockwise, as the crew sees the tank from the bank.

    Args:
        ax: The arena axes; data coordinates are (x, y) in m.
        x_range_m: The x (north) limits to show (m).
        y_range_m: The y (east) limits to show (m).
    """
    ax.set_xlim(x_range_m[0], x_range_m[1])
    ax.set_ylim(y_range_m[1], y_range_m[0])  # y (east) grows downward
    ax.set_aspect("equal")
    ax.set_xlabel("x, north (m) →")
    ax.set_ylabel("y, east (m) ↓")
    ax.set_title(ARENA_TITLE, fontsize=9)


def _label_path(ax: Axes, xy: FloatArray) -> None:
    """Mark and name the start and the end of a path `xy`, shape (N, 2), (x, y) in m."""
    for (x_m, y_m), marker, text in ((xy[0], "o", "start"), (xy[-1], "s", "end")):
        ax.plot(x_m, y_m, marker=marker, color="#1f5fbf", ms=6)
        ax.annotate(
            text,
            (x_m, y_m),
            xytext=(6, 6),
            textcoords="offset points",
            fontsize=8,
            color="#1f5fbf",
            fontweight="bold",
        )


def _draw_obstacles(ax: Axes, run: RunData, scenario: Scenario | None) -> None:
    """Draw the newest layout's real (named) and inflated obstacles; the first one dotted."""
    layouts = run.layouts[-1:]  # the newest layout; moving obstacles: first one dotted
    if len(run.layouts) > 1:
        for poly in run.layouts[0].real:
            x, y = _closed(poly)
            ax.plot(x, y, color="#c0392b", lw=0.8, ls=":")
    for layout in layouts:
        for n, (poly, name) in enumerate(
            zip(layout.real, obstacle_names(scenario, len(layout.real)), strict=True)
        ):
            ax.add_patch(
                PolygonPatch(
                    poly,
                    closed=True,
                    fc="#e8a09a",
                    ec="#c0392b",
                    lw=1.2,
                    label="obstacle" if n == 0 else None,
                )
            )
            cx, cy = np.asarray(poly).mean(axis=0)
            ax.text(cx, cy, name, ha="center", va="center", fontsize=9, fontweight="bold")
        inflated = inflated_outlines(scenario, layout) if scenario is not None else layout.inflated
        for n, poly in enumerate(inflated):
            x, y = _closed(poly)
            ax.plot(
                x,
                y,
                color="#e67e22",
                lw=1.0,
                ls="--",
                label="inflated obstacle" if n == 0 else None,
            )


def draw_arena(ax: Axes, run: RunData, scenario: Scenario | None, hull_every_s: float) -> None:
    """Draw the arena, obstacles, targets, trajectory and hull outlines on `ax`.

    The arena is seen from above (:func:`orient_from_above`); obstacles and the
    target are named, the path's start and end marked.
    """
    if scenario is not None:
        x, y = _closed(scenario.arena.vertices())
        ax.plot(x, y, color="0.3", lw=1.5)
        ax.add_patch(
            PolygonPatch(
                scenario.target.shape.vertices(),
                closed=True,
                fc="#b8e6c1",
                ec="#2a9d48",
                lw=1.2,
                label="target T1",
            )
        )
        tx, ty = scenario.target.shape.vertices().mean(axis=0)
        ax.text(tx, ty, "T1", ha="center", va="center", fontsize=8, color="#2a9d48")
        x, y = _closed(scenario.abstract_target().vertices())
        ax.plot(x, y, color="#2a9d48", lw=1.0, ls="--", label="abstract target T2")
    _draw_obstacles(ax, run, scenario)
    path = run.estimate if len(run.estimate) else run.pose
    xy = path.values[:, :2]
    if len(xy):
        ax.plot(xy[:, 0], xy[:, 1], color="#1f5fbf", lw=1.6, label="trajectory (estimate)")
        _label_path(ax, xy)
    hull = scenario.hull if scenario is not None else Hull()
    for n, i in enumerate(_hull_times(path.t_ns, hull_every_s)):
        x_m, y_m, psi = path.values[i, :3]
        outline = hull_footprint(hull, float(x_m), float(y_m), float(psi)).vertices()
        ax.add_patch(
            PolygonPatch(
                outline,
                closed=True,
                fill=False,
                ec="#34495e",
                lw=0.8,
                label=f"hull every {hull_every_s:g} s" if n == 0 else None,
            )
        )
        bow = np.array([x_m, y_m]) + 0.5 * hull.length_m * np.array([math.cos(psi), math.sin(psi)])
        ax.plot([x_m, bow[0]], [y_m, bow[1]], color="#34495e", lw=0.8)
    if scenario is not None:
        x_lim = (scenario.x_range_m[0] - 0.2, scenario.x_range_m[1] + 0.2)
        y_lim = (scenario.y_range_m[0] - 0.2, scenario.y_range_m[1] + 0.2)
    else:  # what was drawn, still seen from above
        ax.autoscale_view()
        (x0, x1), (y0, y1) = ax.get_xlim(), sorted(ax.get_ylim())
        x_lim, y_lim = (x0, x1), (y0, y1)
    orient_from_above(ax, x_lim, y_lim)
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=8, frameon=False)


def tracking_rms_text(run: RunData) -> tuple[str, str, str]:
    """Return the tracking error's RMS per axis as shown ("" without references)."""
    tracking = run.tracking_error()
    if not len(tracking):
        return ("", "", "")
    rms = for_display(tracking.rms())
    return (
        f"RMS error {rms[0]:.4f} m/s",
        f"RMS error {rms[1]:.4f} m/s",
        f"RMS error {rms[2]:.3f} deg/s",
    )


def draw_velocity(axes: list[Axes], run: RunData) -> None:
    """Draw commanded against estimated velocity, one axis per row, with the tracking RMS."""
    rms_text = tracking_rms_text(run)
    for k, (ax, (label, scale)) in enumerate(zip(axes, _AXES, strict=True)):
        if rms_text[k]:
            ax.set_title(rms_text[k], loc="left", fontsize=8)
        if len(run.reference):
            ax.step(
                run.reference.t_s,
                run.reference.values[:, k] * scale,
                where="post",
                color="#c0392b",
                lw=1.2,
                label="commanded",
            )
        if len(run.estimate):
            ax.plot(
                run.estimate.t_s,
                run.estimate.values[:, 3 + k] * scale,
                color="#1f5fbf",
                lw=1.0,
                label="estimated",
            )
        ax.set_ylabel(label, fontsize=9)
        ax.grid(True, lw=0.3, alpha=0.5)
    axes[0].legend(loc="lower right", bbox_to_anchor=(1.0, 1.0), fontsize=8, ncol=2, frameon=False)
    axes[-1].set_xlabel("time (s)")


def _title(run: RunData, scenario: Scenario | None) -> str:
    info = run.run
    name = scenario.name if scenario is not None else (info.scenario_file if info else "?")
    seed = info.seed if info is not None and info.seed is not None else "-"
    outcome = next(
        (e.code for e in reversed(run.events) if e.code in {"docked", "timeout", "stopped"}), ""
    )
    duration_s = (run.end_ns - run.start_ns) / 1e9
    return (
        f"{run.path.name}: scenario {name}, seed {seed}, {duration_s:.1f} s, "
        f"{len(run.decisions)} decisions" + (f", {outcome}" if outcome else "")
    )


def run_figure(
    run: RunData,
    scenario: Scenario | None,
    hull_every_s: float = HULL_EVERY_S,
) -> Figure:
    """Return the one-page figure of a run (size :data:`FIGURE_SIZE_IN`)."""
    fig = plt.figure(figsize=FIGURE_SIZE_IN)
    grid = fig.add_gridspec(
        3,
        2,
        width_ratios=(1.35, 1.0),
        left=0.06,
        right=0.98,
        top=0.92,
        bottom=0.1,
        wspace=0.18,
        hspace=0.28,
    )
    arena = fig.add_subplot(grid[:, 0])
    draw_arena(arena, run, scenario, hull_every_s)
    first = fig.add_subplot(grid[0, 1])
    velocity = [
        first,
        fig.add_subplot(grid[1, 1], sharex=first),
        fig.add_subplot(grid[2, 1], sharex=first),
    ]
    draw_velocity(velocity, run)
    fig.suptitle(_title(run, scenario), fontsize=11)
    return fig


def save_run_figure(
    run: RunData,
    scenario: Scenario | None,
    path: str | Path,
    dpi: int = DEFAULT_DPI,
    hull_every_s: float = HULL_EVERY_S,
) -> Path:
    """Write the run's figure as a PNG of FIGURE_SIZE_IN x `dpi` pixels; return its path."""
    fig = run_figure(run, scenario, hull_every_s)
    try:
        out = Path(path)
        fig.savefig(out, dpi=dpi, format="png")
    finally:
        plt.close(fig)
    return out
