"""The Rerun viewer's layout, built in code: the arena seen from above beside the time series."""

from __future__ import annotations

from dataclasses import dataclass

import rerun.blueprint as rrb

from hil.scenarios import Scenario
from hil.views.rerun_style import AXES, TIMELINE

ARENA_VIEW_NAME = "arena seen from above (x north right, y east down, z down)"
"""The arena view's title: the frame (``RIGHT_HAND_Z_DOWN``) and where it is seen from."""


@dataclass(frozen=True)
class Eye:
    """Where the arena view's camera stands, in the arena frame (x north, y east, z down).

    Attributes:
        position_m: The eye, shape (3,), (x, y, z) in m; z < 0 is above the water.
        look_target_m: The point looked at, shape (3,), (x, y, z) in m.
        up: The direction drawn upward on the screen, shape (3,), unit vector.
    """

    position_m: tuple[float, float, float]
    look_target_m: tuple[float, float, float]
    up: tuple[float, float, float]


def top_down_eye(scenario: Scenario | None) -> Eye:
    """Return the camera that sees the arena from above, as ``hil plot`` draws it.

    z is down, so the eye stands at negative z and looks along +z; screen-up is -y, so
    x (north) runs right and y (east) down the screen, as in
    :func:`hil.views.plot.orient_from_above`: a starboard turn is drawn clockwise.
    """
    if scenario is not None:
        cx = 0.5 * sum(scenario.x_range_m)
        cy = 0.5 * sum(scenario.y_range_m)
        height_m = 1.1 * max(
            scenario.x_range_m[1] - scenario.x_range_m[0],
            scenario.y_range_m[1] - scenario.y_range_m[0],
        )
    else:
        cx, cy, height_m = 0.0, 0.0, 10.0
    return Eye((cx, cy, -height_m), (cx, cy, 0.0), (0.0, -1.0, 0.0))


def blueprint(scenario: Scenario | None = None, *, replay: bool = False) -> rrb.Blueprint:
    """Return the viewer layout: the arena seen from above beside the time series.

    With `replay`, a tab shows where the replayed decisions differ.
    """
    eye = top_down_eye(scenario)
    arena = rrb.Spatial3DView(
        name=ARENA_VIEW_NAME,
        origin="/world",
        eye_controls=rrb.EyeControls3D(
            position=list(eye.position_m), look_target=list(eye.look_target_m), eye_up=list(eye.up)
        ),
        line_grid=False,
    )
    velocity = rrb.Vertical(
        *(
            rrb.TimeSeriesView(name=f"velocity {label}", origin=f"/plots/velocity/{axis}")
            for axis, label in AXES
        ),
        name="velocity",
    )
    error = rrb.Vertical(
        *(
            rrb.TimeSeriesView(
                name=f"tracking error {label}", origin=f"/plots/tracking_error/{axis}"
            )
            for axis, label in AXES
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
