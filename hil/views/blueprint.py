"""The Rerun viewer's layout, built in code: the arena top-down beside the time series."""

from __future__ import annotations

import rerun.blueprint as rrb

from hil.scenarios import Scenario
from hil.views.rerun_style import AXES, TIMELINE


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
