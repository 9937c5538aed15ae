"""Tests of the compiled low-level loop: same math as the classes, EKF, tracking, errors."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.allocation import MinimumMagnitudeAzimuthAllocator
from hil.controllers.observer import Ekf
from hil.controllers.pid import PidOutput, VelocityPid
from hil.model.environment import EnvironmentalLoad
from hil.model.errors import StateShapeError
from hil.model.thrusters import Thrusters, ThrusterState, throttle_for_slew
from hil.model.vessel import Vessel, VesselState
from hil.sim.closed_loop import (
    AllocatorKind,
    ClosedLoopResult,
    LowLevelConfig,
    simulate_closed_loop,
)
from hil.sim.errors import ClosedLoopConfigError
from hil.sim.sensors import (
    ImuSensorConfig,
    imu_noise_series,
    imu_reading,
    pose_noise_series,
    pose_sensor_step,
)

F = NDArray[np.float64]

REFS = np.array(
    [[0.05, 0.0, 0.0], [0.1, 0.05, 0.1], [0.1, 0.0, 0.2], [0.05, -0.05, 0.1], [0.0, 0.0, 0.0]]
)


def python_loop(refs: F, cfg: LowLevelConfig, eta0: F) -> tuple[F, F]:
    """The same loop written with the Python-level classes; returns (nu, nu_hat) (N, 3)."""
    vessel = Vessel(cfg.vessel, cfg.dt_s, cfg.integrator)
    thrusters = Thrusters(cfg.thrusters)
    alloc = MinimumMagnitudeAzimuthAllocator(cfg.thrusters, replace(cfg.mma, dt_s=0.05))
    pid = VelocityPid(cfg.gains, cfg.vessel, cfg.thrusters, dt_s=cfg.control_period_s)
    n = refs.shape[0] * cfg.steps_per_command
    b = cfg.environment.series(n, cfg.dt_s)
    use_ekf = cfg.observer is not None
    ekf = Ekf(cfg.observer)
    ekf.initialize(0, eta0, np.zeros(3))
    pose_seed, imu_seed = np.random.SeedSequence(cfg.seed).generate_state(2)
    pose = pose_noise_series(cfg.pose_sensor, n, int(pose_seed))
    imu = imu_noise_series(cfg.imu, n, int(imu_seed))
    ring = np.zeros((pose.delay_steps + 1, 4))
    state = VesselState(eta0, np.zeros(3))
    thr = ThrusterState.idle()
    setpoint = ThrusterState.idle()
    tau = np.zeros(3)
    tau_sum = np.zeros(3)
    out = PidOutput(np.zeros(3), np.zeros(3))
    nus = np.empty((n, 3))
    nu_hats = np.empty((n, 3))
    dt_ns = round(cfg.dt_s * 1e9)
    buf = np.zeros(3)
    for k in range(n):
        nu_ref = refs[k // cfg.steps_per_command]
        if use_ekf:
            nu_dot = vessel.acceleration(state.nu, tau, b[max(k - 1, 0)])
            imu_reading(state.nu, nu_dot, imu.noise[k], imu.bias[k], buf)
            ekf.fuse_imu(k * dt_ns, buf[0], buf[1], buf[2])
            k_meas = pose_sensor_step(ring, k, state.eta, pose.noise[k], pose.available[k], buf)
            if k_meas >= 0:
                ekf.fuse_pose(k_meas * dt_ns, buf[0], buf[1], buf[2])
            nu_hat = ekf.estimate().nu
        else:
            nu_hat = state.nu
        if k % cfg.control_every == 0:
            if k > 0:
                pid.update(nu_ref, nu_hat, out, tau_sum / cfg.control_every)
            tau_sum = np.zeros(3)
            out = pid.command(nu_ref, nu_hat)
            res = alloc.allocate(out.tau_n, thr.angles_rad)
            setpoint = ThrusterState(res.commands, res.angles_rad)
        target = ThrusterState(
            throttle_for_slew(setpoint.commands, setpoint.angles_rad, thr.angles_rad),
            setpoint.angles_rad,
        )
        thr = thrusters.step(thr, target, cfg.dt_s)
        tau = thrusters.force(thr)
        tau_sum = tau_sum + tau
        nus[k] = state.nu
        nu_hats[k] = nu_hat
        state = vessel.step(state, tau, b[k])
    return nus, nu_hats


@pytest.mark.parametrize("with_ekf", [False, True])
def test_compiled_loop_equals_python_classes(with_ekf: bool) -> None:
    env = EnvironmentalLoad(constant_n=(0.05, -0.02, 0.01), gm_std_n=(0.05, 0.05, 0.01), seed=2)
    cfg = LowLevelConfig(environment=env, seed=5)
    if not with_ekf:
        cfg = replace(cfg, observer=None)
    eta0 = np.array([1.0, -0.5, 3.0])
    res = simulate_closed_loop(REFS, cfg, eta0=eta0)
    nus, nu_hats = python_loop(REFS, cfg, eta0)
    # Rounding-level agreement: the compiled loop inlines the same kernels, and LLVM
    # may order a few floating-point operations differently (seen: 2e-10 after 10 s
    # with the EKF in the loop).
    tol = 1e-8 if with_ekf else 1e-12
    np.testing.assert_allclose(res.nu, nus, atol=tol, rtol=0)
    np.testing.assert_allclose(res.nu_hat, nu_hats, atol=tol, rtol=0)


def test_outputs_are_time_major_and_consistent() -> None:
    res = simulate_closed_loop(REFS)
    n = REFS.shape[0] * 200
    for name in ("eta", "nu", "nu_hat", "nu_ref", "tau_cmd", "tau", "commands"):
        assert getattr(res, name).shape == (n, 3), name
    assert res.angles_rad.shape == (n, 2)
    np.testing.assert_allclose(res.t_s, np.arange(n) * 0.01)
    np.testing.assert_array_equal(res.nu_ref[::200], REFS)
    assert np.all(np.abs(res.commands[:, 0]) <= 0.7)
    assert np.all(np.abs(res.commands[:, 1:]) <= 1.0)
    assert np.all((res.eta[:, 2] >= -math.pi) & (res.eta[:, 2] < math.pi))
    # Command rate limit: 0.02 per 10-ms step.
    assert np.all(np.abs(np.diff(res.commands, axis=0)) <= 0.02 + 1e-12)


def test_reproducible_per_seed() -> None:
    a = simulate_closed_loop(REFS, LowLevelConfig(seed=1))
    b = simulate_closed_loop(REFS, LowLevelConfig(seed=1))
    c = simulate_closed_loop(REFS, LowLevelConfig(seed=2))
    np.testing.assert_array_equal(a.nu, b.nu)
    assert not np.array_equal(a.nu_hat, c.nu_hat)


def rms(x: F) -> F:
    out: F = np.sqrt(np.mean(x**2, axis=0))
    return out


def test_ekf_in_loop_estimates_velocity() -> None:
    res = simulate_closed_loop(REFS, LowLevelConfig(seed=3))
    err = rms(res.nu_hat - res.nu)
    assert np.all(err < np.array([0.005, 0.005, 0.005]))
    assert np.all(err > 0.0)  # the noise is really there


@pytest.mark.parametrize("allocator", list(AllocatorKind))
def test_tracks_references(allocator: AllocatorKind) -> None:
    res = simulate_closed_loop(REFS, LowLevelConfig(allocator=allocator))
    err = rms(res.nu - res.nu_ref)
    # Mostly the unavoidable transient after each step (bench/lowlevel.py bounds it).
    assert np.all(err < np.array([0.025, 0.025, 0.05]))
    late = settled(res)
    assert np.all(np.abs(late) < np.array([0.008, 0.008, 0.008]))


def settled(res: ClosedLoopResult) -> F:
    """Errors in the second half of every 2-s window."""
    mask = np.mod(res.t_s + 1e-9, 2.0) >= 1.5
    out: F = (res.nu - res.nu_ref)[mask]
    return out


def test_integral_action_rejects_constant_load() -> None:
    refs = np.tile([0.1, 0.0, 0.05], (10, 1))
    env = EnvironmentalLoad(constant_n=(-0.3, 0.2, 0.05))
    res = simulate_closed_loop(refs, LowLevelConfig(environment=env, observer=None))
    np.testing.assert_allclose(res.nu[-1], refs[-1], atol=2e-3)


def test_pid_every_physics_step() -> None:
    res = simulate_closed_loop(REFS, LowLevelConfig(control_period_s=0.01))
    assert np.all(np.abs(settled(res)) < np.array([0.008, 0.008, 0.008]))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"control_period_s": 0.015}, "control_period_s must be a whole multiple"),
        ({"dt_s": -0.01}, "dt_s must be positive"),
        ({"imu": ImuSensorConfig(rate_hz=50.0)}, "imu.rate_hz must equal"),
    ],
)
def test_bad_config_rejected(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(ClosedLoopConfigError, match=match):
        LowLevelConfig(**kwargs)  # type: ignore[arg-type]


def test_bad_inputs_rejected() -> None:
    with pytest.raises(StateShapeError, match="refs must have shape"):
        simulate_closed_loop(np.zeros((3, 2)))
    with pytest.raises(StateShapeError, match="refs must be finite"):
        simulate_closed_loop(np.array([[0.1, math.nan, 0.0]]))
    with pytest.raises(StateShapeError, match="eta0 must have shape"):
        simulate_closed_loop(REFS, eta0=np.zeros(2))
