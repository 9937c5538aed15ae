"""Tests of the low-level tick: its plain twin (PID, allocator and thruster classes), state."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.allocation import (
    MinimumMagnitudeAzimuthAllocator,
    PseudoInverseAllocator,
)
from hil.controllers.low_level import (
    L_A_PRED,
    L_THETA,
    L_U_PRED,
    AllocatorKind,
    LowLevelController,
    LowLevelParams,
)
from hil.controllers.pid import NonFiniteInputError, VelocityPid
from hil.model.thrusters import Thrusters, ThrusterState, throttle_for_slew

F = NDArray[np.float64]


def reference_sequence(n: int, seed: int) -> tuple[F, F]:
    """Return references and estimates (n, 3) with big steps, so the allocator saturates."""
    rng = np.random.default_rng(seed)
    refs = np.repeat(rng.uniform(-0.6, 0.6, (n // 10 + 1, 3)), 10, axis=0)[:n]
    est = refs + rng.normal(scale=0.05, size=(n, 3))
    return refs, est


@pytest.mark.parametrize("kind", list(AllocatorKind))
def test_tick_equals_pid_and_allocator_classes(kind: AllocatorKind) -> None:
    # The twin: the PID's command, the allocator from the pods' angles, the thrusters
    # moved toward the commands over the tick (their own class: rate limits, slew, the
    # throttle while turning), the PID's integrator fed the force they then deliver.
    params = LowLevelParams(allocator=kind)
    thrusters = Thrusters(params.thrusters)
    reached = ThrusterState(np.zeros(3), np.asarray(params.mma.reference_angles_rad, float))
    low = LowLevelController(params)
    pid = VelocityPid(dt_s=params.dt_s)
    alloc = (
        MinimumMagnitudeAzimuthAllocator(config=params.mma)
        if kind is AllocatorKind.MIN_MAGNITUDE_AZIMUTH
        else PseudoInverseAllocator()
    )
    refs, est = reference_sequence(200, 4)
    saturated = 0
    lagging = 0
    for nu_ref, nu_hat in zip(refs, est, strict=True):
        out = low.tick(nu_ref, nu_hat)
        p = pid.command(nu_ref, nu_hat)
        r = alloc.allocate(p.tau_n, reached.angles_rad)
        setpoint = ThrusterState(
            throttle_for_slew(r.commands, r.angles_rad, reached.angles_rad), r.angles_rad
        )
        reached = thrusters.step(reached, setpoint, params.dt_s)
        delivered = thrusters.force(reached)
        pid.update(nu_ref, nu_hat, p, delivered)
        np.testing.assert_allclose(out.tau_n, p.tau_n, atol=1e-12, rtol=0)
        np.testing.assert_allclose(out.commands, r.commands, atol=1e-12, rtol=0)
        np.testing.assert_allclose(out.angles_rad, r.angles_rad, atol=1e-12, rtol=0)
        np.testing.assert_allclose(out.achieved_n, delivered, atol=1e-12, rtol=0)
        np.testing.assert_allclose(low.state[0:3], pid.integrator, atol=1e-12, rtol=0)
        np.testing.assert_allclose(low.state[L_U_PRED : L_U_PRED + 3], reached.commands,
                                   atol=1e-12, rtol=0)
        np.testing.assert_allclose(low.state[L_A_PRED : L_A_PRED + 2], reached.angles_rad,
                                   atol=1e-12, rtol=0)
        if isinstance(alloc, MinimumMagnitudeAzimuthAllocator):
            np.testing.assert_allclose(low.state[L_THETA : L_THETA + 2], alloc.theta, atol=1e-12)
        saturated += int(np.max(np.abs(r.achieved_n - out.tau_n)) > 1e-6)
        lagging += int(np.max(np.abs(delivered - r.achieved_n)) > 1e-6)
    assert saturated > 10  # the sequence exercised the saturated branch
    assert lagging > 10  # ... and thrust still ramping toward the commands


def test_reset_returns_to_rest() -> None:
    params = LowLevelParams()
    low = LowLevelController(params)
    first = low.tick(np.array([0.3, 0.1, 0.2]), np.zeros(3))
    low.tick(np.array([0.3, 0.1, 0.2]), np.array([0.05, 0.0, 0.0]))
    assert not np.array_equal(low.state, params.initial_state())
    low.reset()
    np.testing.assert_array_equal(low.state, params.initial_state())
    again = low.tick(np.array([0.3, 0.1, 0.2]), np.zeros(3))
    np.testing.assert_array_equal(again.commands, first.commands)
    np.testing.assert_array_equal(params.initial_state()[L_A_PRED : L_A_PRED + 2],
                                  params.mma.reference_angles_rad)


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_input_rejected_state_kept(bad: float) -> None:
    low = LowLevelController()
    low.tick(np.array([0.1, 0.0, 0.0]), np.zeros(3))
    before = low.state
    with pytest.raises(NonFiniteInputError, match="nu_hat must be finite"):
        low.tick(np.array([0.1, 0.0, 0.0]), np.array([0.0, bad, 0.0]))
    with pytest.raises(NonFiniteInputError, match="nu_ref must be finite"):
        low.tick(np.array([bad, 0.0, 0.0]), np.zeros(3))
    np.testing.assert_array_equal(low.state, before)


def test_bad_period_rejected() -> None:
    with pytest.raises(ValueError, match="dt_s must be positive"):
        LowLevelParams(dt_s=0.0)
