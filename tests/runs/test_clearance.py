import math

import numpy as np
import pytest

from hil.runs.clearance import hull_clearance_series
from hil.scenarios import load_scenario


def test_matches_the_scalar_geometry_on_random_poses() -> None:
    scenario = load_scenario("coarse")
    rng = np.random.default_rng(7)
    eta = np.column_stack(
        [rng.uniform(-3.5, 4.5, 300), rng.uniform(-3, 3, 300), rng.uniform(-math.pi, math.pi, 300)]
    )
    fast = hull_clearance_series(scenario, eta)
    slow = np.array([scenario.hull_clearance_m(*row) for row in eta])
    np.testing.assert_allclose(fast, slow, atol=1e-9)
    assert (fast == 0.0).any()  # some poses touch an obstacle
    assert (fast > 0.5).any()


def test_known_answer_next_to_o1() -> None:
    scenario = load_scenario("paper")
    # O1 spans x in [1.75, 2.25], y <= 0. Hull along x (0.99 long) centred 1 m right of
    # O1's right face at y = -1: gap = 1.0 - 0.495.
    got = hull_clearance_series(scenario, np.array([[3.25, -1.0, 0.0]]))
    assert got[0] == pytest.approx(1.0 - 0.495)
    # Rotated 90 deg, the beam (0.31) faces O1: gap = 1.0 - 0.155.
    got = hull_clearance_series(scenario, np.array([[3.25, -1.0, math.pi / 2]]))
    assert got[0] == pytest.approx(1.0 - 0.155)
    # Straddling the obstacle: contact.
    assert hull_clearance_series(scenario, np.array([[2.0, -1.0, 0.0]]))[0] == 0.0
