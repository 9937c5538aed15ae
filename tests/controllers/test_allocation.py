"""Tests of thrust allocation: demand reproduced, limits respected, saturation handled."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.allocation import (
    AllocationConfigError,
    Allocator,
    MinimumMagnitudeAzimuthAllocator,
    MmaConfig,
    NonFiniteDemandError,
    PseudoInverseAllocator,
    axis_force_limits,
    bounded_least_squares,
    extended_matrix,
    force_limits,
    matvec,
    null_space_gradient,
    project_feasible,
    xi_to_commands,
)
from hil.model.thrusters import VOYAGER_THRUSTERS, throttle_for_slew, thruster_force

F = NDArray[np.float64]
TP = VOYAGER_THRUSTERS.as_array()
FMAX = np.array([0.7 * 2.629, 1.03, 1.03])


def be_twin() -> F:
    """B_e from the thruster positions: tunnel fy; each azimuth fx, fy."""
    lx_t, (lx_p, ly_p), (lx_s, ly_s) = 0.3875, (-0.4574, -0.055), (-0.4574, 0.055)
    return np.array(
        [
            [0.0, 1.0, 0.0, 1.0, 0.0],
            [1.0, 0.0, 1.0, 0.0, 1.0],
            [lx_t, -ly_p, lx_p, -ly_s, lx_s],
        ]
    )


BE = be_twin()


def random_feasible_xi(rng: np.random.Generator, fill: float) -> F:
    """A random extended force within `fill` times the limits."""
    xi = np.empty(5)
    xi[0] = rng.uniform(-1, 1) * FMAX[0] * fill
    for j in range(2):
        r = math.sqrt(rng.uniform()) * FMAX[1 + j] * fill
        a = rng.uniform(-math.pi, math.pi)
        xi[1 + 2 * j : 3 + 2 * j] = (r * math.cos(a), r * math.sin(a))
    return xi


def residual_twin(tau: F, wq: F) -> F:
    """Least weighted residual over the feasible set for each row of tau (B, 3).

    Brute force: plain (unaccelerated) projected gradient written here with numpy,
    run long, all demands at once.
    """
    h = BE.T @ np.diag(wq**2) @ BE
    g = tau @ np.diag(wq**2) @ BE  # (B, 5)
    step = 1.0 / np.linalg.eigvalsh(h).max()
    x = np.zeros((tau.shape[0], 5))
    for _ in range(20000):
        x = x - step * (x @ h - g)
        x[:, 0] = np.clip(x[:, 0], -FMAX[0], FMAX[0])
        for j in range(2):
            f = x[:, 1 + 2 * j : 3 + 2 * j]
            n = np.maximum(np.hypot(f[:, 0], f[:, 1]), 1e-300)
            f *= np.minimum(1.0, FMAX[1 + j] / n)[:, None]
    out: F = np.linalg.norm((x @ BE.T - tau) * wq, axis=1)
    return out


def applied(commands: F, angles: F) -> F:
    return thruster_force(TP, commands, angles)


def check_limits(commands: F) -> None:
    assert abs(commands[0]) <= 0.7 + 1e-12
    assert np.all(np.abs(commands[1:]) <= 1.0 + 1e-12)


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


def test_throttle_for_slew() -> None:
    u = np.array([0.5, 0.8, 0.8])
    out = throttle_for_slew(u, np.array([0.0, 0.0]), np.array([math.pi / 3, 2.0]))
    np.testing.assert_allclose(out, [0.5, 0.4, 0.0], atol=1e-12)


def test_axis_force_limits() -> None:
    lim = axis_force_limits()
    assert lim[0] == pytest.approx(2.06)  # both azimuths ahead
    assert lim[1] == pytest.approx(1.8403 + 2.06)  # tunnel plus both azimuths abeam
    assert lim[2] == pytest.approx(0.3875 * 1.8403 + 2 * math.hypot(0.4574, 0.055) * 1.03)


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
