"""Scenarios: hull clearance, moved obstacle layouts, the digest."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.core.shapes import Rect
from hil.core.transient import TransientBudget
from hil.scenarios import ScenarioError, load_scenario


def test_hull_clearance_closed_form() -> None:
    s = load_scenario("paper")
    # Hull 0.99 x 0.31 at (1, 1) heading 0: corner (1.495, 0.845) to O1's corner (1.75, 0).
    assert s.hull_clearance_m(1.0, 1.0, 0.0) == pytest.approx(math.hypot(0.255, 0.845))
    # Turned 90 deg: corner (1.155, 0.505).
    assert s.hull_clearance_m(1.0, 1.0, math.pi / 2) == pytest.approx(math.hypot(0.595, 0.505))
    assert s.hull_clearance_m(2.0, -1.0, 0.3) == 0.0  # inside O1
    assert s.wall_clearance_m(0.0, 0.0, 0.0) == pytest.approx(3.0 - 0.155)


def test_moved_layout_keeps_the_rest() -> None:
    s = load_scenario("coarse")
    moved = s.with_obstacles_moved(np.array([[0.5, -0.25]]))
    assert len(moved.obstacles) == 1
    assert moved.obstacles[0].name == s.obstacles[0].name
    assert moved.obstacles[0].shape == Rect(-0.75, -0.25, -0.25, 2.75)
    assert moved.target == s.target
    assert moved.cell_m == s.cell_m
    assert moved.transient == s.transient
    with pytest.raises(ScenarioError, match="overlaps"):
        s.with_obstacles_moved(np.array([[-1.5, 0.0]]))  # onto the target
    with pytest.raises(ValueError, match="reshape"):
        s.with_obstacles_moved(np.array([[0.5, 0.0], [0.0, -0.25]]))  # one offset per obstacle


def test_digest_follows_the_content() -> None:
    s = load_scenario("coarse")
    assert s.digest() == load_scenario("coarse").digest()
    assert s.digest() != s.with_obstacles_moved(np.array([[0.1, 0.0]])).digest()


def test_with_transient_replaces_the_budget_and_the_digest() -> None:
    s = load_scenario("coarse")
    zero = s.with_transient(TransientBudget.zero(s.tau_s))
    assert zero.transient.is_zero()
    assert zero.digest() != s.digest()
    assert zero.with_transient(s.transient) == s
    assert zero.with_transient(s.transient).digest() == s.digest()
    with pytest.raises(ScenarioError, match=r"with 9 bins covers 4.5 s, not a period held late"):
        s.with_transient(TransientBudget.zero(2 * s.tau_s))
    with pytest.raises(ScenarioError, match=r"12 bins covers 3.0 s, .* \(need 9 bins\)"):
        s.with_transient(TransientBudget.zero(s.tau_s, 12))
