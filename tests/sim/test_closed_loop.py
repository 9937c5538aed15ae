"""Tests of the compiled low-level loop: pinned to the runtime's low level, EKF, tracking."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.low_level import AllocatorKind, LowLevelController
from hil.model.environment import EnvironmentalLoad
from hil.model.errors import StateShapeError
from hil.runtime.assembly import PidAllocator
from hil.sim.closed_loop import (
    ClosedLoopResult,
    LowLevelConfig,
    initial_plant,
    simulate_closed_loop,
)
from hil.sim.errors import ClosedLoopConfigError
from hil.sim.plant import N_TRACE, P_ALPHA, P_NU, P_U, TR_ETA, TR_NU, TR_TAU, plant_step
from hil.sim.sensors import ImuSensorConfig

F = NDArray[np.float64]

REFS = np.array(
    [[0.05, 0.0, 0.0], [0.1, 0.05, 0.1], [0.1, 0.0, 0.2], [0.05, -0.05, 0.1], [0.0, 0.0, 0.0]]
)
# Large steps as well, so the allocator saturates and the anti-windup acts.
HARD_REFS = np.array([[0.6, 0.0, 0.0], [-0.2, 0.3, 0.0], [0.0, 0.0, 0.6], [0.0, -0.1, -0.3]])


def runtime_low_level_loop(refs: F, cfg: LowLevelConfig, eta0: F) -> dict[str, F]:
    """The runtime's low-level object driving :func:`plant_step`, true velocity fed back.

    Returns the per-physics-step series named as in :class:`ClosedLoopResult`.
    """
    low_level = PidAllocator(LowLevelController(cfg.low_level()))
    m_inv, coef = cfg.vessel.kernel_arrays()
    tp = cfg.thrusters.as_array()
    n = refs.shape[0] * cfg.steps_per_command
    b = cfg.environment.series(n, cfg.dt_s)
    plant = initial_plant(cfg.low_level(), eta0, np.zeros(3))
    u_set = np.zeros(3)
    a_set = plant[P_ALPHA : P_ALPHA + 2].copy()
    tau_cmd = np.zeros(3)
    trace = np.zeros(N_TRACE)
    names = ("eta", "nu", "tau_cmd", "tau", "commands", "angles_rad", "setpoints",
             "setpoint_angles_rad")
    out = {name: np.empty((n, 2 if "angles" in name else 3)) for name in names}
    dt_ns = round(cfg.dt_s * 1e9)
    for k in range(n):
        nu_ref = refs[k // cfg.steps_per_command]
        if k % cfg.control_every == 0:
            step = low_level.step(nu_ref, plant[P_NU : P_NU + 3].copy(), k * dt_ns)
            tau_cmd = step.tau
            c = step.command
            u_set = np.array([c.tunnel, c.port, c.starboard])
            a_set = np.array([c.port_angle_rad, c.starboard_angle_rad])
        plant_step(m_inv, coef, tp, int(cfg.integrator), cfg.dt_s, plant, u_set, a_set, b[k],
                   trace)
        out["eta"][k] = trace[TR_ETA : TR_ETA + 3]
        out["nu"][k] = trace[TR_NU : TR_NU + 3]
        out["tau_cmd"][k] = tau_cmd
        out["tau"][k] = trace[TR_TAU : TR_TAU + 3]
        out["commands"][k] = plant[P_U : P_U + 3]
        out["angles_rad"][k] = plant[P_ALPHA : P_ALPHA + 2]
        out["setpoints"][k] = u_set
        out["setpoint_angles_rad"][k] = a_set
    return out


@pytest.mark.parametrize("allocator", list(AllocatorKind))
@pytest.mark.parametrize("refs", [REFS, HARD_REFS], ids=["grid", "saturating"])
def test_compiled_loop_is_the_runtime_low_level_tick_for_tick(
    allocator: AllocatorKind, refs: F
) -> None:
    env = EnvironmentalLoad(constant_n=(0.05, -0.02, 0.01), gm_std_n=(0.05, 0.05, 0.01), seed=2)
    cfg = LowLevelConfig(environment=env, observer=None, allocator=allocator)
    eta0 = np.array([1.0, -0.5, 3.0])
    res = simulate_closed_loop(refs, cfg, eta0=eta0)
    twin = runtime_low_level_loop(refs, cfg, eta0)
    for name, series in twin.items():
        np.testing.assert_allclose(getattr(res, name), series, atol=1e-9, rtol=0, err_msg=name)
    # The pinned run is not trivial: the pods turn and the thrust reaches its limits.
    assert np.ptp(res.setpoint_angles_rad) > 1.0
    if refs is HARD_REFS:
        assert np.max(np.abs(res.setpoints[:, 1:])) == pytest.approx(1.0)


def test_outputs_are_time_major_and_consistent() -> None:
    res = simulate_closed_loop(REFS)
    n = REFS.shape[0] * 200
    for name in ("eta", "nu", "nu_hat", "eta_hat", "nu_ref", "tau_cmd", "tau", "commands"):
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


def test_ekf_in_loop_estimates_the_pose() -> None:
    res = simulate_closed_loop(REFS, LowLevelConfig(seed=3))
    position = np.hypot(*(res.eta_hat[:, :2] - res.eta[:, :2]).T)
    heading = np.abs(np.angle(np.exp(1j * (res.eta_hat[:, 2] - res.eta[:, 2]))))
    assert 0.0 < position.max() < 0.01  # m: motion capture at 100 Hz, mm noise
    assert 0.0 < heading.max() < 0.01  # rad
    exact = simulate_closed_loop(REFS, LowLevelConfig(observer=None))
    np.testing.assert_array_equal(exact.eta_hat, exact.eta)


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
