"""Tests of the MIMO velocity PID: kernel twin, step settling, anti-windup, bad input."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.pid import (
    DEFAULT_GAINS,
    N_PID_STATE,
    NonFiniteInputError,
    PidConfigError,
    PidGains,
    PidOutput,
    VelocityPid,
    pid_command,
    pid_integrate,
)
from hil.model.coefficients import ENTERPRISE_I
from hil.model.dynamics import hydro_force
from hil.sim.closed_loop import LowLevelConfig, simulate_closed_loop

F = NDArray[np.float64]
M = ENTERPRISE_I.mass_matrix()
COEF = ENTERPRISE_I.kernel_arrays()[1]
GAINS = replace(DEFAULT_GAINS, kd=(0.3, 0.2, 0.1), kaw=(0.5, 0.3, 0.1), tau_max_n=(1.5, 2.5, 1.0))
G = GAINS.as_array()
# The real plant under the vessel's low level: the compiled loop, true velocity fed back.
TRUE_STATE = LowLevelConfig(observer=None)


def pid_twin(z: F, dfilt: F, nu_prev: F, nu_ref: F, nu_hat: F, dt: float) -> tuple[F, F, F]:
    """The law of the module docstring, written with numpy; returns (tau, raw, dfilt)."""
    kp, ki, kd = (np.asarray(x) for x in (GAINS.kp_per_s, GAINS.ki_per_s2, GAINS.kd))
    a = dt / (GAINS.derivative_tc_s + dt)
    dfilt = dfilt + a * ((nu_hat - nu_prev) / dt - dfilt)
    e = nu_ref - nu_hat
    cap = np.sqrt(2.0 * np.asarray(GAINS.brake_jerk) * np.abs(e))
    p = np.clip(kp * e, -cap, cap)
    raw = M @ (p + ki * z - kd * dfilt) + hydro_force(COEF, nu_ref)
    lim = np.asarray(GAINS.tau_max_n)
    return np.clip(raw, -lim, lim), raw, dfilt


def test_kernels_match_numpy_twin() -> None:
    rng = np.random.default_rng(0)
    s = np.zeros(N_PID_STATE)
    s[9] = 1.0  # started
    s[0:3] = rng.normal(scale=0.05, size=3)
    s[3:6] = rng.normal(scale=0.1, size=3)
    s[6:9] = rng.normal(scale=0.1, size=3)
    for _ in range(20):
        nu_ref = rng.uniform(-0.2, 0.2, 3)
        nu_hat = rng.uniform(-0.2, 0.2, 3)
        tau, raw, s_new = pid_command(G, M, COEF, s, nu_ref, nu_hat, 0.05)
        t_tau, t_raw, t_d = pid_twin(s[0:3], s[3:6], s[6:9], nu_ref, nu_hat, 0.05)
        np.testing.assert_allclose(raw, t_raw, atol=1e-12)
        np.testing.assert_allclose(tau, t_tau, atol=1e-12)
        np.testing.assert_allclose(s_new[3:6], t_d, atol=1e-12)
        np.testing.assert_array_equal(s_new[6:9], nu_hat)
        # Integrator: back-calculation, and no integration where the demand was missed.
        ach = np.clip(raw, -0.5, 0.5)
        z_new = pid_integrate(G, M, s_new, nu_ref, nu_hat, raw, ach, 0.05)[0:3]
        e = nu_ref - nu_hat
        short = ach - raw
        limited = np.abs(short) > GAINS.integrate_tolerance * (1 + np.abs(raw))
        e_used = np.where(limited, 0.0, e)
        ki = np.asarray(GAINS.ki_per_s2)
        back = np.asarray(GAINS.kaw) * short / (ki * np.diag(M))
        np.testing.assert_allclose(z_new, s_new[0:3] + 0.05 * (e_used + back), atol=1e-12)
        s = s_new


def test_feedforward_holds_steady_velocity() -> None:
    pid = VelocityPid()
    nu = np.array([0.1, 0.05, -0.1])
    out = pid.command(nu, nu)
    np.testing.assert_allclose(out.tau_n, hydro_force(COEF, nu), atol=1e-12)


def test_output_limits() -> None:
    pid = VelocityPid(GAINS)
    for axis, sign in ((0, 1.0), (1, -1.0), (2, 1.0)):
        ref = np.zeros(3)
        ref[axis] = sign
        out = pid.command(ref, np.zeros(3))
        lim = np.asarray(GAINS.tau_max_n)
        np.testing.assert_allclose(out.tau_n, np.clip(out.tau_raw_n, -lim, lim))
        assert out.tau_n[axis] == sign * lim[axis]


@pytest.mark.parametrize(
    ("axis", "step"),
    [(0, 0.05), (0, 0.1), (0, -0.1), (1, 0.05), (1, -0.1), (2, 0.1), (2, 0.2), (2, -0.2)],
)
def test_step_settles_within_command_period(axis: int, step: float) -> None:
    refs = np.zeros((2, 3))
    refs[1, axis] = step
    res = simulate_closed_loop(refs, TRUE_STATE)
    window = slice(200, 400)  # the 2-s window after the step
    err = np.abs(res.nu[window, axis] - step) / abs(step)
    t = res.t_s[window] - 2.0
    # Settled: within 5 % of the step from 1.5 s on, and no more than 5 % overshoot (the
    # anti-windup sees the thrust the thrusters deliver while it ramps, see low_level).
    assert np.all(err[t >= 1.5] < 0.05)
    assert np.max(np.sign(step) * (res.nu[window, axis] - step)) < 0.05 * abs(step)
    # The other axes stay near zero (couplings are rejected within the window).
    others = [i for i in range(3) if i != axis]
    assert np.all(np.abs(res.nu[399, others]) < 0.1 * abs(step))


def windup_run(protected: bool) -> F:
    """Ask for an unreachable surge speed for 20 s, then 0.1 m/s for 10 s; return u after."""
    gains = replace(DEFAULT_GAINS, anti_windup=protected)
    refs = np.zeros((15, 3))
    refs[:10, 0] = 1.5  # top speed is about 0.78 m/s
    refs[10:, 0] = 0.1
    res = simulate_closed_loop(refs, replace(TRUE_STATE, gains=gains))
    out: F = res.nu[2000:, 0]
    return out


def test_no_windup_after_saturation() -> None:
    u = windup_run(protected=True)
    t = np.arange(u.size) * 0.01
    # Full reverse thrust bleeds 0.78 -> 0.1 m/s in about 5 s; then it holds, without
    # the undershoot a wound-up integrator would cause.
    assert np.all(np.abs(u[t >= 7.0] - 0.1) < 0.005)
    assert u.min() > 0.1 - 0.01


def test_windup_shows_without_protection() -> None:
    # The same run with anti-windup off: the wound-up integrator keeps pushing ahead
    # and the speed does not come back within the 10 s, so the check above can fail.
    u = windup_run(protected=False)
    assert u[-1] > 0.1 + 0.3


def test_integrator_frozen_while_saturated() -> None:
    pid = VelocityPid()
    ref = np.array([1.0, 0.0, 0.0])
    for _ in range(100):
        out = pid.command(ref, np.zeros(3))
        pid.update(ref, np.zeros(3), out, out.tau_n)
    # The demand is capped every period, so the error never enters the integrator.
    assert pid.integrator[0] == 0.0
    # Once the achieved force matches the demand it integrates again.
    out = pid.command(np.array([0.01, 0.0, 0.0]), np.zeros(3))
    pid.update(np.array([0.01, 0.0, 0.0]), np.zeros(3), out, out.tau_raw_n)
    assert pid.integrator[0] == pytest.approx(0.05 * 0.01)
    pid.reset()
    assert np.all(pid.integrator == 0.0)


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_input_rejected_state_kept(bad: float) -> None:
    pid = VelocityPid()
    ref = np.array([0.1, 0.0, 0.0])
    out = pid.command(ref, np.zeros(3))
    pid.update(ref, np.zeros(3), out, np.zeros(3))
    before = pid.integrator
    with pytest.raises(NonFiniteInputError, match="nu_hat must be finite"):
        pid.command(ref, np.array([bad, 0.0, 0.0]))
    with pytest.raises(NonFiniteInputError, match="tau_achieved must be finite"):
        pid.update(ref, np.zeros(3), PidOutput(np.zeros(3), np.zeros(3)), np.full(3, bad))
    np.testing.assert_array_equal(pid.integrator, before)


def test_bad_gains_rejected() -> None:
    with pytest.raises(PidConfigError, match="kp_per_s must be 3 finite non-negative"):
        PidGains(kp_per_s=(1.0, -1.0, 1.0))
    with pytest.raises(PidConfigError, match="tau_max_n must be positive"):
        PidGains(tau_max_n=(1.0, 0.0, 1.0))
    with pytest.raises(PidConfigError, match="dt_s must be positive"):
        VelocityPid(dt_s=0.0)
