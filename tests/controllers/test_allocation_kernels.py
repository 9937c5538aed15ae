"""Allocation kernels against numpy twins and finite differences."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.controllers.allocation_kernels import (
    bounded_least_squares,
    extended_matrix,
    force_limits,
    matvec,
    null_space_gradient,
    project_feasible,
    xi_to_commands,
)
from tests.controllers.allocation_twins import (
    BE,
    FMAX,
    TP,
    F,
    applied,
    check_limits,
    random_feasible_xi,
    residual_twin,
)


def test_extended_matrix_matches_twin() -> None:
    np.testing.assert_allclose(extended_matrix(TP), BE, atol=1e-15)


def test_matvec_and_projection_match_numpy() -> None:
    rng = np.random.default_rng(0)
    a = rng.normal(size=(3, 5))
    x = rng.normal(size=5)
    np.testing.assert_allclose(matvec(a, x), a @ x, atol=1e-14)
    np.testing.assert_allclose(force_limits(TP), FMAX)
    xi = rng.normal(size=5) * 3
    p = project_feasible(xi, FMAX)
    assert p[0] == np.clip(xi[0], -FMAX[0], FMAX[0])
    for j in range(2):
        v = xi[1 + 2 * j : 3 + 2 * j]
        np.testing.assert_allclose(
            p[1 + 2 * j : 3 + 2 * j], v * min(1.0, FMAX[1 + j] / np.linalg.norm(v))
        )


def test_commands_reproduce_extended_force() -> None:
    rng = np.random.default_rng(1)
    for _ in range(100):
        xi = random_feasible_xi(rng, 1.0)
        hold = rng.uniform(-math.pi, math.pi, 2)
        u, alpha = xi_to_commands(TP, xi, hold, 1e-9)
        np.testing.assert_allclose(applied(u, alpha), BE @ xi, atol=1e-12)
        check_limits(u)
        # Never turns a pod more than 90 deg from where it was: reverses instead.
        turn = (alpha - hold + math.pi) % (2 * math.pi) - math.pi
        assert np.all(np.abs(turn) <= math.pi / 2 + 1e-12)


def test_bounded_least_squares_kernel_matches_twin() -> None:
    rng = np.random.default_rng(4)
    wq = np.array([1.0, 1.0, 2.0])
    taus = rng.normal(size=(10, 3)) * 3.0
    best = residual_twin(taus, wq)
    for tau, least in zip(taus, best, strict=True):
        xi = bounded_least_squares(BE, tau, FMAX, np.zeros(5), wq, 1e-6, 300)
        assert np.linalg.norm(wq * (BE @ xi - tau)) == pytest.approx(least, abs=1e-4)
        assert np.all(np.abs(project_feasible(xi, FMAX) - xi) < 1e-15)


def test_null_space_gradient_matches_finite_difference() -> None:
    rng = np.random.default_rng(5)
    a_ref = np.array([[0.0, 1.0], [0.0, -1.0]])
    w = np.array([1.0, 2.0, 0.5])
    lam, eps = 0.3, 0.02

    def cost(xi: F) -> float:
        j = w[0] * math.sqrt(xi[0] ** 2 + eps**2)
        for k in range(2):
            f = xi[1 + 2 * k : 3 + 2 * k]
            j += w[1 + k] * (math.sqrt(f @ f + eps**2) - lam * a_ref[k] @ f)
        return float(j)

    for _ in range(10):
        xi = rng.normal(size=5)
        num = np.array([(cost(xi + 1e-6 * e) - cost(xi - 1e-6 * e)) / 2e-6 for e in np.eye(5)])
        np.testing.assert_allclose(null_space_gradient(xi, a_ref, w, lam, eps), num, atol=1e-6)
