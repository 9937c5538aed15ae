"""Allocators: demand reproduced, limits respected, saturation handled, bad input refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.controllers.allocation import (
    Allocator,
    MinimumMagnitudeAzimuthAllocator,
    MmaConfig,
    PseudoInverseAllocator,
)
from hil.controllers.errors import AllocationConfigError, NonFiniteDemandError
from tests.controllers.allocation_twins import (
    BE,
    applied,
    check_limits,
    random_feasible_xi,
    residual_twin,
)


@pytest.mark.parametrize("kind", ["pinv", "mma"])
def test_random_feasible_demands_reproduced(kind: str) -> None:
    rng = np.random.default_rng(2)
    alloc: Allocator = (
        PseudoInverseAllocator() if kind == "pinv" else MinimumMagnitudeAzimuthAllocator()
    )
    fill = 0.45 if kind == "pinv" else 0.95  # pinv ignores the null space, so it saturates early
    # Near the envelope's edge the bounded solve ends within 1e-5 N; inside it is exact.
    tol = 1e-9 if kind == "pinv" else 1e-5
    for _ in range(200):
        tau = BE @ random_feasible_xi(rng, fill)
        for _ in range(3):  # a few calls: the null-space state moves between them
            res = alloc.allocate(tau)
            np.testing.assert_allclose(applied(res.commands, res.angles_rad), tau, atol=tol)
            np.testing.assert_allclose(res.achieved_n, tau, atol=tol)
            check_limits(res.commands)


def test_mma_beyond_saturation_as_close_as_possible() -> None:
    rng = np.random.default_rng(3)
    alloc = MinimumMagnitudeAzimuthAllocator()
    pinv = PseudoInverseAllocator()
    wq = np.asarray(alloc.config.residual_weights)  # the norm the allocator minimizes
    taus = rng.normal(size=(15, 3)) * np.array([4.0, 6.0, 2.5])
    best = residual_twin(taus, wq)
    for tau, least in zip(taus, best, strict=True):
        res = alloc.allocate(tau)
        check_limits(res.commands)
        err = float(np.linalg.norm(wq * (applied(res.commands, res.angles_rad) - tau)))
        assert err <= least + 1e-4
        # Plain clipping does worse than (or at best as well as) the bounded solve.
        clipped = pinv.allocate(tau)
        check_limits(clipped.commands)
        assert err <= float(np.linalg.norm(wq * (clipped.achieved_n - tau))) + 1e-9


def test_mma_step_matches_numpy_twin() -> None:
    # One step of the law for a demand that fits: xi = B_w^+ tau + Q theta', with
    # theta' = theta - dt gamma Q^T dJ/dxi(B_w^+ tau + Q theta); B_e xi = tau exactly.
    alloc = MinimumMagnitudeAzimuthAllocator()
    cfg = alloc.config
    q = alloc.arrays.q
    np.testing.assert_allclose(BE @ q, 0.0, atol=1e-14)
    np.testing.assert_allclose(q.T @ q, np.eye(2), atol=1e-14)
    b_pinv = BE.T @ np.linalg.inv(BE @ BE.T)  # unit column weights
    a_ref = np.array([[0.0, 1.0], [0.0, -1.0]])
    w = np.asarray(cfg.cost_weights)
    rng = np.random.default_rng(8)
    theta = np.zeros(2)
    for _ in range(30):
        tau = BE @ random_feasible_xi(rng, 0.3)
        xi_d = b_pinv @ tau + q @ theta
        grad = np.empty(5)
        grad[0] = w[0] * xi_d[0] / math.sqrt(xi_d[0] ** 2 + cfg.eps_n**2)
        for k in range(2):
            f = xi_d[1 + 2 * k : 3 + 2 * k]
            grad[1 + 2 * k : 3 + 2 * k] = w[1 + k] * (
                f / math.sqrt(f @ f + cfg.eps_n**2) - cfg.lam * a_ref[k]
            )
        theta = theta - cfg.dt_s * cfg.gamma_nps * q.T @ grad
        res = alloc.allocate(tau)
        np.testing.assert_allclose(alloc.theta, theta, atol=1e-12)
        np.testing.assert_allclose(res.xi_n, b_pinv @ tau + q @ theta, atol=1e-12)


def test_mma_pulls_azimuths_toward_reference_angles() -> None:
    tau = np.array([1.0, 0.0, 0.0])

    def port_angle(lam: float) -> float:
        res = None
        alloc = MinimumMagnitudeAzimuthAllocator(config=MmaConfig(lam=lam))
        for _ in range(200):  # 10 s at 20 Hz: the null-space term settles
            res = alloc.allocate(tau)
        assert res is not None
        np.testing.assert_allclose(applied(res.commands, res.angles_rad), tau, atol=1e-9)
        return float(res.angles_rad[0])

    plain = port_angle(0.0)
    pulled = port_angle(0.6)
    assert abs(plain) < 0.05  # minimum magnitude: both pods push straight ahead
    assert pulled > 0.3  # port pod leans toward its +pi/2 reference


def test_mma_zero_demand_gives_zero_thrust() -> None:
    alloc = MinimumMagnitudeAzimuthAllocator()
    for _ in range(20):
        res = alloc.allocate(np.zeros(3))
    np.testing.assert_allclose(res.commands, 0.0, atol=1e-12)
    np.testing.assert_allclose(res.angles_rad, [math.pi / 2, -math.pi / 2])


@pytest.mark.parametrize("kind", ["pinv", "mma"])
def test_pods_turn_at_most_90_degrees_from_measured_angles(kind: str) -> None:
    rng = np.random.default_rng(7)
    alloc: Allocator = (
        PseudoInverseAllocator() if kind == "pinv" else MinimumMagnitudeAzimuthAllocator()
    )
    for _ in range(50):
        now = rng.uniform(-math.pi, math.pi, 2)
        tau = BE @ random_feasible_xi(rng, 0.4)
        res = alloc.allocate(tau, now)
        turn = (res.angles_rad - now + math.pi) % (2 * math.pi) - math.pi
        assert np.all(np.abs(turn) <= math.pi / 2 + 1e-12)
        np.testing.assert_allclose(applied(res.commands, res.angles_rad), tau, atol=1e-9)
    with pytest.raises(NonFiniteDemandError, match="pod angles must be finite"):
        alloc.allocate(np.zeros(3), np.array([0.0, math.nan]))


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_demand_rejected(bad: float) -> None:
    for alloc in (PseudoInverseAllocator(), MinimumMagnitudeAzimuthAllocator()):
        with pytest.raises(NonFiniteDemandError, match="force demand must be finite"):
            alloc.allocate(np.array([0.0, bad, 0.0]))


def test_bad_config_rejected() -> None:
    with pytest.raises(AllocationConfigError, match="lam must be in"):
        MmaConfig(lam=1.0)
    with pytest.raises(AllocationConfigError, match="weights must be positive"):
        MmaConfig(column_weights=(1.0, 0.0, 1.0, 1.0, 1.0))
    with pytest.raises(AllocationConfigError, match="shape"):
        PseudoInverseAllocator().allocate(np.zeros(4))


def test_reset_restores_initial_state() -> None:
    alloc = MinimumMagnitudeAzimuthAllocator()
    first = alloc.allocate(np.array([0.5, 0.2, 0.1]))
    for _ in range(10):
        alloc.allocate(np.array([-0.5, 0.3, -0.2]))
    alloc.reset()
    again = alloc.allocate(np.array([0.5, 0.2, 0.1]))
    np.testing.assert_array_equal(first.commands, again.commands)
    np.testing.assert_array_equal(first.angles_rad, again.angles_rad)
