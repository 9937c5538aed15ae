"""Tests of the thruster model: B(alpha) K u, saturation and rate limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.model.errors import NonFiniteCommandError, StateShapeError, VesselConfigError
from hil.model.thrusters import (
    VOYAGER_THRUSTERS,
    ThrusterParams,
    Thrusters,
    ThrusterState,
    throttle_for_slew,
    thrust_matrix,
    thruster_force,
    thruster_update,
)

F = NDArray[np.float64]
TP = VOYAGER_THRUSTERS.as_array()


def b_twin(alpha: F) -> F:
    """B(alpha) from VESSEL.md: columns [cos a; sin a; lx sin a - ly cos a]."""
    pos = [(0.3875, 0.0, math.pi / 2), (-0.4574, -0.055, alpha[0]), (-0.4574, 0.055, alpha[1])]
    return np.array(
        [[math.cos(a), math.sin(a), lx * math.sin(a) - ly * math.cos(a)] for lx, ly, a in pos]
    ).T


def test_force_matches_numpy_twin() -> None:
    rng = np.random.default_rng(0)
    k = np.diag([2.629, 1.03, 1.03])
    for _ in range(50):
        alpha = rng.uniform(-math.pi, math.pi, 2)
        u = rng.uniform(-1, 1, 3)
        np.testing.assert_allclose(thrust_matrix(TP, alpha), b_twin(alpha), atol=1e-15)
        np.testing.assert_allclose(thruster_force(TP, u, alpha), b_twin(alpha) @ k @ u, atol=1e-14)


def update_twin(u: F, a: F, uc: F, ac: F, dt: float) -> tuple[F, F]:
    """Saturate, then rate-limit commands; turn pods the short way at the slew limit."""
    lim = np.array([0.7, 1.0, 1.0])
    step = 2.0 * dt
    u_new = u + np.clip(np.clip(uc, -lim, lim) - u, -step, step)
    diff = (ac - a + math.pi) % (2 * math.pi) - math.pi
    a_new = a + np.clip(diff, -math.pi * dt, math.pi * dt)
    return u_new, (a_new + math.pi) % (2 * math.pi) - math.pi


def test_update_matches_numpy_twin() -> None:
    rng = np.random.default_rng(1)
    for dt in (0.01, 0.05, 0.5):
        for _ in range(50):
            u, uc = rng.uniform(-1, 1, 3), rng.uniform(-2, 2, 3)
            a, ac = rng.uniform(-math.pi, math.pi, 2), rng.uniform(-math.pi, math.pi, 2)
            got_u, got_a = thruster_update(TP, u, a, uc, ac, dt)
            want_u, want_a = update_twin(u, a, uc, ac, dt)
            np.testing.assert_allclose(got_u, want_u, atol=1e-14)
            np.testing.assert_allclose(got_a, want_a, atol=1e-12)


def test_known_forces() -> None:
    thr = Thrusters()
    # Both azimuths forward at full command: 2 x 1.03 N surge, no moment (symmetric).
    tau = thr.force(ThrusterState(np.array([0.0, 1.0, 1.0]), np.zeros(2)))
    np.testing.assert_allclose(tau, [2.06, 0.0, 0.0], atol=1e-12)
    # Tunnel alone at 0.7: 0.7 x 2.629 N to starboard, moment 0.3875 times that.
    tau = thr.force(ThrusterState(np.array([0.7, 0.0, 0.0]), np.zeros(2)))
    np.testing.assert_allclose(tau, [0.0, 1.8403, 0.3875 * 1.8403], atol=1e-12)


def test_saturation_and_command_rate_limit() -> None:
    u = np.zeros(3)
    a = np.zeros(2)
    target = np.array([1.0, 5.0, -5.0])
    u1, _ = thruster_update(TP, u, a, target, a, 0.05)
    np.testing.assert_allclose(u1, [0.1, 0.1, -0.1])  # 0.1 per 20-Hz step
    for _ in range(100):
        u, a = thruster_update(TP, u, a, target, a, 0.01)
    np.testing.assert_allclose(u, [0.7, 1.0, -1.0])  # tunnel 0.7, azimuths 1


def test_azimuth_rate_limit_takes_short_way() -> None:
    rate = VOYAGER_THRUSTERS.azimuth_rate_radps
    u = np.zeros(3)
    _, a = thruster_update(TP, u, np.array([0.0, 3.0]), u, np.array([1.0, -3.0]), 0.1)
    assert a[0] == pytest.approx(0.1 * rate)
    # From 3.0 to -3.0 the short way crosses +-pi (0.283 rad < 0.1 * rate), not
    # back through 0 (6 rad).
    assert a[1] == pytest.approx(-3.0)
    steps = 0
    a = np.array([0.0, 3.0])
    while not np.allclose(a, [1.0, -3.0]):
        _, a = thruster_update(TP, u, a, u, np.array([1.0, -3.0]), 0.01)
        assert np.all((a >= -math.pi) & (a < math.pi))
        steps += 1
    assert steps == math.ceil(1.0 / (0.01 * rate))


def test_step_api_matches_kernel() -> None:
    thr = Thrusters()
    state = ThrusterState.idle()
    setpoint = ThrusterState(np.array([0.5, -0.5, 0.2]), np.array([0.0, 0.5]))
    nxt = thr.step(state, setpoint, 0.01)
    u, a = thruster_update(
        TP, state.commands, state.angles_rad, setpoint.commands, setpoint.angles_rad, 0.01
    )
    np.testing.assert_array_equal(nxt.commands, u)
    np.testing.assert_array_equal(nxt.angles_rad, a)


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_commands_rejected(bad: float) -> None:
    with pytest.raises(NonFiniteCommandError, match="commands must be finite"):
        ThrusterState(np.array([0.0, bad, 0.0]), np.zeros(2))
    with pytest.raises(NonFiniteCommandError, match="angles_rad must be finite"):
        ThrusterState(np.zeros(3), np.array([bad, 0.0]))


def test_bad_shapes_and_params_rejected() -> None:
    with pytest.raises(StateShapeError, match="commands must have shape"):
        ThrusterState(np.zeros(2), np.zeros(2))
    with pytest.raises(VesselConfigError, match="tunnel_limit"):
        ThrusterParams(tunnel_limit=1.5)
    with pytest.raises(VesselConfigError, match="thrust gains must be positive"):
        ThrusterParams(gains_n=(2.629, -1.0, 1.03))
    with pytest.raises(VesselConfigError, match="rate limits"):
        ThrusterParams(azimuth_rate_radps=0.0)
    with pytest.raises(VesselConfigError, match="dt_s"):
        Thrusters().step(ThrusterState.idle(), ThrusterState.idle(), -1.0)


def test_max_thrust() -> None:
    np.testing.assert_allclose(VOYAGER_THRUSTERS.max_thrust_n(), [1.8403, 1.03, 1.03])


def test_throttle_for_slew() -> None:
    u = np.array([0.5, 0.8, 0.8])
    out = throttle_for_slew(u, np.array([0.0, 0.0]), np.array([math.pi / 3, 2.0]))
    np.testing.assert_allclose(out, [0.5, 0.4, 0.0], atol=1e-12)
