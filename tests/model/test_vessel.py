"""The vessel: integration against closed forms, and the checks of its Python face."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from hil.model.dynamics import Integrator, euler_step, hydro_force
from hil.model.errors import NonFiniteForceError, StateShapeError, VesselConfigError
from hil.model.vessel import Vessel, VesselState
from tests.model.twins import COEF, M_INV, F, M, P, accel_twin, rot


def test_invalid_dt_refused() -> None:
    with pytest.raises(VesselConfigError, match="dt_s"):
        Vessel(dt_s=0.0)


@pytest.mark.parametrize("integrator", list(Integrator))
def test_zero_force_from_rest_stays_at_rest(integrator: Integrator) -> None:
    vessel = Vessel(integrator=integrator)
    eta, nu = vessel.simulate(VesselState.at_rest(1.0, -2.0, 0.5), np.zeros((3000, 3)))
    assert np.all(nu == 0.0)
    assert np.all(eta == np.array([1.0, -2.0, 0.5]))


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
