"""Tests of the 3-DOF vessel model against closed forms and numpy twins."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.model.errors import (
    NonFiniteForceError,
    StateShapeError,
    VesselConfigError,
)
from hil.model.vessel import (
    ENTERPRISE_I,
    Integrator,
    Vessel,
    VesselParams,
    VesselState,
    acceleration,
    coriolis_matrix,
    damping_matrix,
    euler_step,
    hydro_force,
    rk4_step,
    simulate_kernel,
)

F = NDArray[np.float64]
P = ENTERPRISE_I
M_INV, COEF = P.kernel_arrays()
M = P.mass_matrix()

# Operating range of the paper (input set U1), widened a little.
U_RANGE = (-0.15, 0.25)
V_RANGE = (-0.15, 0.15)
R_RANGE = (-0.3, 0.3)


# ---- numpy twins, written from VESSEL.md independently of the kernels ----


def c_twin(nu: F) -> F:
    u, v, r = nu
    m, xg = P.m_kg, P.xg_m
    c13 = (-m * xg + P.y_rdot) * r + (-m + P.y_vdot) * v
    c23 = (m - P.x_udot) * u
    return np.array([[0.0, 0.0, c13], [0.0, 0.0, c23], [-c13, -c23, 0.0]])


def d_twin(nu: F) -> F:
    u, v, r = nu
    p = P
    d11 = -p.xu - p.xuu * abs(u) - p.xuuu * u**2
    d22 = -p.yv - p.yvv * abs(v) - p.yvvv * v**2 - p.yrv * abs(r)
    d23 = -p.yr - p.yrr * abs(r) - p.yrrr * r**2 - p.yvr * abs(v)
    d32 = -p.nv - p.nvv * abs(v) - p.nvvv * v**2 - p.nrv * abs(r)
    d33 = -p.nr - p.nrr * abs(r) - p.nrrr * r**2 - p.nvr * abs(v)
    return np.array([[d11, 0.0, 0.0], [0.0, d22, d23], [0.0, d32, d33]])


def accel_twin(nu: F, force: F) -> F:
    out = np.linalg.solve(M, force - (c_twin(nu) + d_twin(nu)) @ nu)
    return np.asarray(out, dtype=np.float64)


def rot(psi: float) -> F:
    c, s = math.cos(psi), math.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def random_nu(rng: np.random.Generator) -> F:
    return np.array([rng.uniform(*U_RANGE), rng.uniform(*V_RANGE), rng.uniform(*R_RANGE)])


# ---- parameters ----


def test_mass_matrix_matches_published() -> None:
    expected = np.array([[16.11, 0.0, 0.0], [0.0, 24.11, 0.5291], [0.0, 0.5291, 2.76]])
    np.testing.assert_allclose(M, expected, atol=1e-3)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"m_kg": -14.11}, "mass m_kg must be positive, got -14.11"),
        ({"iz_kgm2": 0.0}, "inertia iz_kgm2 must be positive"),
        ({"iz_kgm2": 0.01, "n_rdot": 0.0}, "not positive definite"),
        ({"y_rdot": 1.0}, "must be symmetric"),
        ({"xu": math.nan}, "xu must be finite"),
    ],
)
def test_invalid_configuration_refused(change: dict[str, float], match: str) -> None:
    with pytest.raises(VesselConfigError, match=match):
        replace(P, **change)  # type: ignore[arg-type]


def test_invalid_dt_refused() -> None:
    with pytest.raises(VesselConfigError, match="dt_s"):
        Vessel(dt_s=0.0)


# ---- kernels against numpy twins ----


def test_kernels_match_numpy_twins() -> None:
    rng = np.random.default_rng(1)
    for _ in range(50):
        nu = random_nu(rng)
        force = rng.normal(size=3)
        np.testing.assert_allclose(coriolis_matrix(COEF, nu), c_twin(nu), atol=1e-14)
        np.testing.assert_allclose(damping_matrix(COEF, nu), d_twin(nu), atol=1e-14)
        np.testing.assert_allclose(
            hydro_force(COEF, nu), (c_twin(nu) + d_twin(nu)) @ nu, atol=1e-14
        )
        np.testing.assert_allclose(
            acceleration(M_INV, COEF, nu, force), accel_twin(nu, force), atol=1e-12
        )


def test_euler_step_matches_paper_update() -> None:
    rng = np.random.default_rng(2)
    for _ in range(20):
        eta = np.array([rng.normal(), rng.normal(), rng.uniform(-math.pi, math.pi)])
        nu = random_nu(rng)
        force = rng.normal(size=3)
        eta1, nu1 = euler_step(M_INV, COEF, eta, nu, force, 0.01)
        eta_twin = eta + 0.01 * rot(eta[2]) @ nu
        eta_twin[2] = (eta_twin[2] + math.pi) % (2 * math.pi) - math.pi
        np.testing.assert_allclose(eta1, eta_twin, atol=1e-12)
        np.testing.assert_allclose(nu1, nu + 0.01 * accel_twin(nu, force), atol=1e-12)


def test_rk4_step_matches_numpy_twin() -> None:
    rng = np.random.default_rng(3)
    eta = np.array([0.3, -0.2, 3.1])
    nu = random_nu(rng)
    force = rng.normal(size=3)
    dt = 0.05

    def f(x: F) -> F:
        return np.concatenate([rot(x[2]) @ x[3:], accel_twin(x[3:], force)])

    x = np.concatenate([eta, nu])
    k1 = f(x)
    k2 = f(x + 0.5 * dt * k1)
    k3 = f(x + 0.5 * dt * k2)
    k4 = f(x + dt * k3)
    x1 = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    eta1, nu1 = rk4_step(M_INV, COEF, eta, nu, force, dt)
    np.testing.assert_allclose(nu1, x1[3:], atol=1e-12)
    np.testing.assert_allclose(eta1[:2], x1[:2], atol=1e-12)
    assert eta1[2] == pytest.approx((x1[2] + math.pi) % (2 * math.pi) - math.pi, abs=1e-12)


# ---- physics ----


@pytest.mark.parametrize("integrator", list(Integrator))
def test_zero_force_from_rest_stays_at_rest(integrator: Integrator) -> None:
    vessel = Vessel(integrator=integrator)
    eta, nu = vessel.simulate(VesselState.at_rest(1.0, -2.0, 0.5), np.zeros((3000, 3)))
    assert np.all(nu == 0.0)
    assert np.all(eta == np.array([1.0, -2.0, 0.5]))


def test_linearization_is_stable() -> None:
    eig = np.linalg.eigvals(M_INV @ damping_matrix(COEF, np.zeros(3)))
    assert np.all(eig.real > 0.0)
    np.testing.assert_allclose(np.sort(eig.real), [0.041, 0.061, 0.628], atol=1e-3)


def test_damping_not_strictly_dissipative_as_documented() -> None:
    # What the docstring says: nu^T D nu < 0 where v and r have opposite signs.
    nu = np.array([0.0, -0.2, 0.4])
    assert nu @ damping_matrix(COEF, nu) @ nu == pytest.approx(-0.159, abs=1e-3)
    sym = damping_matrix(COEF, np.zeros(3))
    eig = np.linalg.eigvalsh(0.5 * (sym + sym.T))
    np.testing.assert_allclose(eig, [-2.01, 0.66, 5.26], atol=0.01)


def test_coasts_to_rest_from_anywhere_in_operating_range() -> None:
    rng = np.random.default_rng(4)
    corners = [np.array([u, v, r]) for u in U_RANGE for v in V_RANGE for r in R_RANGE]
    starts = corners + [random_nu(rng) for _ in range(12)]
    force = np.zeros((4000, 3))  # 400 s at 0.1 s (RK4)
    for i, nu0 in enumerate(starts):
        _, nu = simulate_kernel(M_INV, COEF, np.zeros(3), nu0, force, 0.1, 1)
        energy = 0.5 * np.einsum("ki,ij,kj->k", nu, M, nu)
        assert np.all(np.isfinite(nu))
        if i < len(corners):
            # D is not dissipative everywhere, so energy may grow at first (up to
            # 8.7 % from these corners, measured) before it decays.
            assert energy.max() <= 1.1 * energy[0]
        assert np.linalg.norm(nu[-1]) < 1e-6
        assert energy[-1] < 1e-8 * energy[0]


def test_kinetic_energy_conserved_without_damping_under_rk4() -> None:
    # With D off, d/dt (nu^T M nu / 2) = -nu^T C(nu) nu = 0 (C skew-symmetric).
    vessel = Vessel(replace(P, damping_enabled=False), dt_s=0.01, integrator=Integrator.RK4)
    nu0 = np.array([0.2, 0.1, 0.2])
    _, nu = vessel.simulate(VesselState(np.zeros(3), nu0), np.zeros((6000, 3)))
    energy = 0.5 * np.einsum("ki,ij,kj->k", nu, M, nu)
    # Stated tolerance: relative drift below 1e-10 over 60 s at dt = 0.01 s.
    assert np.max(np.abs(energy - energy[0])) / energy[0] < 1e-10
    assert not np.allclose(nu[-1], nu0, atol=1e-3)  # it does move: C rotates nu


def test_constant_surge_force_converges_to_analytic_speed() -> None:
    x_force = 1.0

    def residual(u: float) -> float:
        d11 = -P.xu - P.xuu * abs(u) - P.xuuu * u * u
        return d11 * u - x_force

    lo, hi = 0.0, 2.0  # bisection: d11(u) u is increasing on [0, 2]
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if residual(mid) < 0.0 else (lo, mid)
    u_ss = 0.5 * (lo + hi)
    vessel = Vessel(integrator=Integrator.RK4, dt_s=0.05)
    force = np.tile([x_force, 0.0, 0.0], (4000, 1))
    _, nu = vessel.simulate(VesselState.at_rest(), force)
    assert nu[-1, 0] == pytest.approx(u_ss, abs=1e-9)
    assert np.all(np.abs(nu[:, 1:]) < 1e-15)


def test_euler_converges_to_rk4_as_dt_shrinks() -> None:
    t_end = 10.0
    rng = np.random.default_rng(5)
    knots = rng.normal(scale=1.0, size=(11, 3))

    def force_at(t: F) -> F:
        # Piecewise constant on whole seconds, so every dt below hits the knots.
        out: F = knots[np.floor(t + 1e-9).astype(int)]
        return out

    def final_state(dt: float, integrator: Integrator) -> F:
        n = round(t_end / dt)
        force = force_at(np.arange(n, dtype=np.float64) * dt)
        vessel = Vessel(dt_s=dt, integrator=integrator)
        eta, nu = vessel.simulate(VesselState.at_rest(), force)
        return np.concatenate([eta[-1], nu[-1]])

    ref = final_state(0.001, Integrator.RK4)
    errors = [np.max(np.abs(final_state(dt, Integrator.EULER) - ref)) for dt in (0.02, 0.01, 0.005)]
    assert errors[0] > errors[1] > errors[2]
    # First order: halving dt halves the error.
    assert errors[1] / errors[2] == pytest.approx(2.0, rel=0.15)
    assert np.max(np.abs(final_state(0.01, Integrator.RK4) - ref)) < 1e-7


def closed_form_displacement(nu: F, t: float) -> F:
    u, v, r = nu
    if r == 0.0:
        return np.array([u * t, v * t])
    return np.array(
        [
            (u * math.sin(r * t) + v * (math.cos(r * t) - 1.0)) / r,
            (u * (1.0 - math.cos(r * t)) + v * math.sin(r * t)) / r,
        ]
    )


@pytest.mark.parametrize(
    ("nu", "psi0"),
    [
        (np.array([0.2, 0.0, 0.0]), 0.3),
        (np.array([0.1, -0.1, 0.0]), -2.0),
        (np.array([0.15, 0.05, 0.2]), 2.9),
        (np.array([-0.1, 0.1, -0.2]), -3.0),
    ],
)
def test_kinematics_match_closed_form(nu: F, psi0: float) -> None:
    # Hold nu constant by applying exactly the force that balances C and D.
    t_end = 30.0
    vessel = Vessel(dt_s=0.01, integrator=Integrator.RK4)
    force = np.tile(hydro_force(COEF, nu), (round(t_end / 0.01), 1))
    eta, nus = vessel.simulate(VesselState(np.array([1.0, 2.0, psi0]), nu), force)
    np.testing.assert_allclose(nus[-1], nu, atol=1e-12)
    d = closed_form_displacement(nu, t_end)
    expected_xy = np.array([1.0, 2.0]) + rot(psi0)[:2, :2] @ d
    np.testing.assert_allclose(eta[-1, :2], expected_xy, atol=1e-8)
    psi_end = (psi0 + nu[2] * t_end + math.pi) % (2 * math.pi) - math.pi
    assert eta[-1, 2] == pytest.approx(psi_end, abs=1e-9)
    assert np.all((eta[:, 2] >= -math.pi) & (eta[:, 2] < math.pi))


# ---- bad input ----


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_force_rejected(bad: float) -> None:
    vessel = Vessel()
    with pytest.raises(NonFiniteForceError, match="tau has a non-finite entry"):
        vessel.step(VesselState.at_rest(), np.array([0.0, bad, 0.0]))
    with pytest.raises(NonFiniteForceError, match="b has a non-finite entry"):
        vessel.step(VesselState.at_rest(), np.zeros(3), np.array([bad, 0.0, 0.0]))
    series = np.zeros((5, 3))
    series[3, 2] = bad
    with pytest.raises(NonFiniteForceError, match=r"index \(3, 2\)"):
        vessel.simulate(VesselState.at_rest(), series)


def test_bad_state_shape_rejected() -> None:
    with pytest.raises(StateShapeError, match="eta must have shape"):
        VesselState(np.zeros(2), np.zeros(3))
    with pytest.raises(StateShapeError, match="nu must be finite"):
        VesselState(np.zeros(3), np.array([0.0, math.nan, 0.0]))


def test_step_matches_kernel_and_python_api() -> None:
    vessel = Vessel(integrator=Integrator.EULER)
    state = VesselState(np.array([0.0, 0.0, 0.1]), np.array([0.1, 0.0, 0.05]))
    tau = np.array([0.5, -0.2, 0.1])
    b = np.array([0.05, 0.0, 0.0])
    nxt = vessel.step(state, tau, b)
    eta, nu = euler_step(M_INV, COEF, state.eta, state.nu, tau + b, 0.01)
    np.testing.assert_array_equal(nxt.eta, eta)
    np.testing.assert_array_equal(nxt.nu, nu)
    np.testing.assert_allclose(vessel.acceleration(state.nu, tau, b), accel_twin(state.nu, tau + b))


def test_params_kernel_arrays_respect_damping_switch() -> None:
    _, coef = VesselParams(damping_enabled=False).kernel_arrays()
    assert np.all(damping_matrix(coef, np.array([0.2, 0.1, 0.3])) == 0.0)
