"""The abstract problem of a scenario: obstacles that move are grown by their reach."""

from __future__ import annotations

import dataclasses

import pytest

from hil.controllers.symbolic import SymbolicProblem
from hil.core.shapes import Polygon, Rect
from hil.core.transient import LATE_S
from hil.scenarios import ObstacleTracking, load_scenario


def test_fixed_obstacles_enter_the_problem_as_they_are() -> None:
    scenario = load_scenario("paper")
    problem = SymbolicProblem.from_scenario(scenario)
    assert problem.obstacles == tuple(o.shape for o in scenario.obstacles)
    assert problem.inflation_m == 0.5


def test_a_tracked_obstacle_is_grown_by_speed_times_age_tau_and_late_plus_its_lag() -> None:
    paper = load_scenario("paper")
    o1, o2 = paper.obstacles
    tilted = Polygon.rotated_rect((3.0, 1.0), (0.6, 0.2), 0.4)
    scenario = dataclasses.replace(
        paper,
        obstacles=(
            o1,
            dataclasses.replace(o2, max_speed_mps=0.05),
            dataclasses.replace(o2, name="boat", shape=tilted, max_speed_mps=0.1),
        ),
        tracking=ObstacleTracking(max_report_age_s=1.5, position_tolerance_m=0.02),
    )
    problem = SymbolicProblem.from_scenario(scenario)
    horizon_s = 1.5 + 2.0 + LATE_S  # report age + tau + a late tick: 3.6 s
    assert problem.obstacles[0] == o1.shape  # fixed: not grown
    grown = problem.obstacles[1]
    assert isinstance(grown, Rect)
    r = 0.05 * horizon_s + 0.02  # 0.2 m on every side: motion, and the tracker's lag
    assert (grown.x_min_m, grown.x_max_m, grown.y_min_m, grown.y_max_m) == pytest.approx(
        (-1.25 - r, -0.75 + r, 0.0 - r, 3.0 + r)
    )
    # A polygon's edges move out by the reach: its width across each edge grows by 2 r.
    boat = problem.obstacles[2].vertices()
    assert boat.shape == (4, 2)
    along = boat[1] - boat[0]
    across = boat[2] - boat[1]
    assert float((along**2).sum() ** 0.5) == pytest.approx(0.6 + 2 * (0.1 * horizon_s + 0.02))
    assert float((across**2).sum() ** 0.5) == pytest.approx(0.2 + 2 * (0.1 * horizon_s + 0.02))
    # The centre still keeps the paper's 0.5 m from the grown obstacle.
    assert problem.inflation_m == 0.5
