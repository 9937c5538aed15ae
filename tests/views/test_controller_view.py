"""Predicted arcs against the kinematic model integrated step by step."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.views.controller_view import predicted_arcs


def _integrate(state: tuple[float, float, float], nu: np.ndarray, tau_s: float) -> np.ndarray:
    """Return (x, y) after tau of eta_dot = R(psi) nu, by small Euler steps."""
    x, y, psi = state
    n = 20_000
    dt = tau_s / n
    for _ in range(n):
        x += dt * (math.cos(psi) * nu[0] - math.sin(psi) * nu[1])
        y += dt * (math.sin(psi) * nu[0] + math.cos(psi) * nu[1])
        psi += dt * nu[2]
    return np.array([x, y])


@pytest.mark.parametrize("state", [(0.0, 0.0, 0.0), (1.5, -2.0, 2.5), (-3.0, 1.0, -math.pi)])
def test_arc_end_matches_the_integrated_kinematics(state: tuple[float, float, float]) -> None:
    inputs = np.array([[0.2, 0.0, 0.0], [0.1, -0.1, 0.2], [-0.1, 0.1, -0.2], [0.0, 0.0, 0.1]])
    arcs = predicted_arcs(state, inputs, 2.0, n_points=9)
    assert arcs.shape == (4, 9, 2)
    np.testing.assert_allclose(arcs[:, 0], np.tile(state[:2], (4, 1)))
    for arc, nu in zip(arcs, inputs, strict=True):
        np.testing.assert_allclose(arc[-1], _integrate(state, nu, 2.0), atol=2e-5)


def test_straight_input_gives_evenly_spaced_points_along_the_heading() -> None:
    arcs = predicted_arcs((1.0, 2.0, math.pi / 2), np.array([[0.2, 0.0, 0.0]]), 2.0, n_points=5)
    np.testing.assert_allclose(arcs[0, :, 0], 1.0, atol=1e-12)
    np.testing.assert_allclose(arcs[0, :, 1], 2.0 + np.linspace(0.0, 0.4, 5))


def test_no_inputs_give_no_arcs() -> None:
    assert predicted_arcs((0.0, 0.0, 0.0), np.zeros((0, 3)), 2.0).shape == (0, 16, 2)
