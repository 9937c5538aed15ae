"""The whole low level in one compiled loop: sensors -> EKF -> PID -> allocation -> vessel.

One ``@njit`` loop at the physics rate (100 Hz by default) built only from the kernels
the Python-level classes use (:mod:`hil.model.dynamics`, :mod:`hil.model.thrusters`,
:mod:`hil.controllers.allocation_kernels`, :mod:`hil.controllers.pid`, and the observer's
kernels), so a 3-minute run takes a fraction of a second and there is one copy of the
math. Per physics step k (t = k dt):

1. sensors: pose and IMU samples of the true state, with pre-generated noise;
2. observer: the EKF fuses them (or the true velocity is used, ``observer=False``);
3. every ``control_every`` steps: PID on the current reference -> force demand ->
   allocation -> thruster setpoints; the PID integrator sees the achieved force;
4. thrusters move toward their setpoints within their rate limits;
5. the vessel advances one step under thrust plus environmental load.

The reference sequence is held ``command_period_s`` (2 s) per row, as the symbolic
layer issues it.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from hil.controllers.allocation import MmaArrays, MmaConfig
from hil.controllers.allocation_kernels import (
    extended_matrix,
    mma_allocate,
    pseudo_inverse_allocate,
)
from hil.controllers.observer import ObserverConfig
from hil.controllers.observer_arrays import EkfArrays
from hil.controllers.observer_kernels import obs_imu, obs_init, obs_pose
from hil.controllers.pid import DEFAULT_GAINS, N_PID_STATE, PidGains, pid_command, pid_integrate
from hil.core.jit import njit
from hil.model.coefficients import ENTERPRISE_I, VesselParams
from hil.model.dynamics import Integrator, acceleration, integrate_step
from hil.model.environment import EnvironmentalLoad
from hil.model.errors import StateShapeError
from hil.model.thrusters import (
    VOYAGER_THRUSTERS,
    ThrusterParams,
    throttle_for_slew,
    thruster_force,
    thruster_update,
)
from hil.sim.errors import ClosedLoopConfigError
from hil.sim.sensors import (
    ImuSensorConfig,
    PoseSensorConfig,
    imu_noise_series,
    imu_reading,
    pose_noise_series,
    pose_sensor_step,
)

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


class AllocatorKind(enum.IntEnum):
    """Which allocator the loop runs; the value is what the kernel receives."""

    PSEUDO_INVERSE = 0
    MIN_MAGNITUDE_AZIMUTH = 1


@dataclass(frozen=True)
class LowLevelConfig:
    """Configuration of the simulated low level.

    Attributes:
        vessel: Model coefficients.
        thrusters: Thruster geometry and limits.
        gains: PID gains.
        allocator: Which allocator to run.
        mma: Settings of the minimum-magnitude-and-azimuth allocator (its ``dt_s`` is
            replaced by ``control_period_s``).
        environment: Environmental load b(t) (zero by default).
        dt_s: Physics step (s), 0.01 as in the paper.
        integrator: Vessel integrator.
        control_period_s: PID and allocation period (s): 0.05 (20 Hz) by default;
            ``dt_s`` runs them every physics step. Must be a multiple of ``dt_s``.
        command_period_s: How long each reference row is held (s).
        observer: EKF settings; None feeds the PID the true velocity (no sensors).
        pose_sensor: Motion-capture model (its rate must be 1 / dt_s).
        imu: IMU model (its rate must be 1 / dt_s).
        seed: Seed of the sensor noise and of the environmental load's noise.
    """

    vessel: VesselParams = ENTERPRISE_I
    thrusters: ThrusterParams = VOYAGER_THRUSTERS
    gains: PidGains = DEFAULT_GAINS
    allocator: AllocatorKind = AllocatorKind.MIN_MAGNITUDE_AZIMUTH
    mma: MmaConfig = field(default_factory=MmaConfig)
    environment: EnvironmentalLoad = field(default_factory=EnvironmentalLoad)
    dt_s: float = 0.01
    integrator: Integrator = Integrator.EULER
    control_period_s: float = 0.05
    command_period_s: float = 2.0
    observer: ObserverConfig | None = field(default_factory=ObserverConfig)
    pose_sensor: PoseSensorConfig = field(default_factory=PoseSensorConfig)
    imu: ImuSensorConfig = field(default_factory=ImuSensorConfig)
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("dt_s", "control_period_s", "command_period_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ClosedLoopConfigError(f"{name} must be positive, got {value!r}")
        for name in ("control_period_s", "command_period_s"):
            ratio = getattr(self, name) / self.dt_s
            if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
                raise ClosedLoopConfigError(
                    f"{name} must be a whole multiple of dt_s={self.dt_s!r}, "
                    f"got {getattr(self, name)!r}"
                )
        for name, rate in (("pose_sensor", self.pose_sensor.rate_hz), ("imu", self.imu.rate_hz)):
            if abs(rate * self.dt_s - 1.0) > 1e-9:
                raise ClosedLoopConfigError(
                    f"{name}.rate_hz must equal 1 / dt_s = {1.0 / self.dt_s!r}, got {rate!r}"
                )

    @property
    def control_every(self) -> int:
        """Physics steps per control step."""
        return round(self.control_period_s / self.dt_s)

    @property
    def steps_per_command(self) -> int:
        """Physics steps per reference row."""
        return round(self.command_period_s / self.dt_s)


@dataclass(frozen=True)
class ClosedLoopResult:
    """Time-major series of one closed-loop run, sampled at every physics step.

    Row k is the state at t = k dt (before step k) and what was applied over step k.

    Attributes:
        t_s: Times, shape (N,) (s).
        eta: True pose (x, y, psi), shape (N, 3).
        nu: True body velocity (u, v, r), shape (N, 3).
        nu_hat: Velocity the controller used (estimate), shape (N, 3).
        nu_ref: Reference in force, shape (N, 3).
        tau_cmd: PID force demand, shape (N, 3) (N, N, N m).
        tau: Thrust actually applied to the hull, shape (N, 3).
        commands: Applied thruster commands (tunnel, port, starboard), shape (N, 3).
        angles_rad: Applied azimuth angles (port, starboard), shape (N, 2).
    """

    t_s: FloatArray
    eta: FloatArray
    nu: FloatArray
    nu_hat: FloatArray
    nu_ref: FloatArray
    tau_cmd: FloatArray
    tau: FloatArray
    commands: FloatArray
    angles_rad: FloatArray


@njit
def closed_loop_kernel(
    m_inv: FloatArray,
    coef: FloatArray,
    m: FloatArray,
    method: int,
    dt: float,
    tp: FloatArray,
    alloc_kind: int,
    be: FloatArray,
    b_pinv: FloatArray,
    q: FloatArray,
    acfg: FloatArray,
    a_ref: FloatArray,
    aw: FloatArray,
    wq: FloatArray,
    g: FloatArray,
    control_every: int,
    steps_per_ref: int,
    eta0: FloatArray,
    nu0: FloatArray,
    refs: FloatArray,
    b_env: FloatArray,
    use_observer: bool,
    ekf: EkfArrays,
    pose_noise: FloatArray,
    pose_available: BoolArray,
    pose_ring: FloatArray,
    imu_noise: FloatArray,
    imu_bias: FloatArray,
    out: FloatArray,
) -> None:
    """Run the loop and write row k of ``out`` (see :func:`unpack` for the columns).

    Args:
        m_inv: Vessel M^-1, shape (3, 3).
        coef: Vessel coefficient array.
        m: Vessel M, shape (3, 3).
        method: Vessel integrator (:class:`Integrator` value).
        dt: Physics step (s).
        tp: Thruster parameter array.
        alloc_kind: :class:`AllocatorKind` value.
        be: Extended configuration matrix, (3, 5).
        b_pinv: Its (weighted) pseudo-inverse, (5, 3).
        q: Null-space basis, (5, 2).
        acfg: Allocator settings, (6,).
        a_ref: Azimuth reference directions, (2, 2).
        aw: Allocator cost weights, (3,).
        wq: Allocator residual weights, (3,).
        g: PID gain array.
        control_every: Physics steps per control step.
        steps_per_ref: Physics steps per reference row.
        eta0: Initial pose, (3,).
        nu0: Initial velocity, (3,).
        refs: References, (N_ref, 3).
        b_env: Environmental load per step, (N, 3).
        use_observer: Feed the PID the EKF's velocity (else the true one).
        ekf: Initialized EKF arrays (updated in place).
        pose_noise: Pose noise per step, (N, 3).
        pose_available: Pose availability per step, (N,).
        pose_ring: Pose delay line, (delay + 1, 4), zeros.
        imu_noise: IMU white noise per step, (N, 3).
        imu_bias: IMU bias per step, (N, 3).
        out: Output buffer, (N, N_OUT), N = N_ref * steps_per_ref.
    """
    n = refs.shape[0] * steps_per_ref
    dt_ns = round(dt * 1e9)
    eta = eta0.copy()
    nu = nu0.copy()
    u_act = np.zeros(3)
    a_act = np.empty(2)
    for j in range(2):
        a_act[j] = math.atan2(a_ref[j, 1], a_ref[j, 0])
    u_set = np.zeros(3)
    a_set = a_act.copy()
    theta = np.zeros(2)
    s = np.zeros(N_PID_STATE)
    tau_cmd = np.zeros(3)
    tau_raw = np.zeros(3)
    tau = np.zeros(3)
    tau_sum = np.zeros(3)
    imu_buf = np.zeros(3)
    pose_buf = np.zeros(3)
    nu_hat = nu.copy()
    ctrl_dt = control_every * dt
    for k in range(n):
        nu_ref = refs[k // steps_per_ref]
        if use_observer:
            # Sensors see the state at t_k; the accelerometer the force of the last step.
            nu_dot = acceleration(m_inv, coef, nu, tau + b_env[max(k - 1, 0)])
            imu_reading(nu, nu_dot, imu_noise[k], imu_bias[k], imu_buf)
            obs_imu(ekf, k * dt_ns, imu_buf[0], imu_buf[1], imu_buf[2])
            k_meas = pose_sensor_step(pose_ring, k, eta, pose_noise[k], pose_available[k], pose_buf)
            if k_meas >= 0:
                obs_pose(ekf, k_meas * dt_ns, pose_buf[0], pose_buf[1], pose_buf[2])
            nu_hat = ekf.x[3:6].copy()
        else:
            nu_hat = nu.copy()
        if k % control_every == 0:
            if k > 0:
                # Anti-windup on the thrust the hull actually got over the last period.
                tau_mean = tau_sum / control_every
                s = pid_integrate(g, m, s, nu_ref, nu_hat, tau_raw, tau_mean, ctrl_dt)
            tau_sum[:] = 0.0
            tau_cmd, tau_raw, s = pid_command(g, m, coef, s, nu_ref, nu_hat, ctrl_dt)
            # The allocator turns pods at most 90 deg from where they are now.
            if alloc_kind == 1:
                u_set, a_set, _, theta = mma_allocate(
                    tp, be, b_pinv, q, theta, tau_cmd, a_act, acfg, a_ref, aw, wq
                )
            else:
                u_set, a_set, _ = pseudo_inverse_allocate(tp, b_pinv, tau_cmd, a_act)
        u_act, a_act = thruster_update(
            tp, u_act, a_act, throttle_for_slew(u_set, a_set, a_act), a_set, dt
        )
        tau = thruster_force(tp, u_act, a_act)
        tau_sum += tau
        row = out[k]
        row[0] = k * dt
        row[1:4] = eta
        row[4:7] = nu
        row[7:10] = nu_hat
        row[10:13] = nu_ref
        row[13:16] = tau_cmd
        row[16:19] = tau
        row[19:22] = u_act
        row[22:24] = a_act
        eta, nu = integrate_step(m_inv, coef, eta, nu, tau + b_env[k], dt, method)


N_OUT = 24


def unpack(out: FloatArray) -> ClosedLoopResult:
    """Split the kernel's (N, 24) buffer into a :class:`ClosedLoopResult`."""
    return ClosedLoopResult(
        t_s=out[:, 0].copy(),
        eta=out[:, 1:4].copy(),
        nu=out[:, 4:7].copy(),
        nu_hat=out[:, 7:10].copy(),
        nu_ref=out[:, 10:13].copy(),
        tau_cmd=out[:, 13:16].copy(),
        tau=out[:, 16:19].copy(),
        commands=out[:, 19:22].copy(),
        angles_rad=out[:, 22:24].copy(),
    )


def simulate_closed_loop(
    refs: FloatArray,
    config: LowLevelConfig | None = None,
    eta0: FloatArray | None = None,
    nu0: FloatArray | None = None,
) -> ClosedLoopResult:
    """Run the compiled low level against a reference sequence.

    Args:
        refs: Velocity references (u, v, r), shape (N_ref, 3), each held
            ``config.command_period_s``.
        config: Loop configuration (defaults: Enterprise I, Voyager thrusters, 20-Hz
            PID and allocation, sensors and EKF on).
        eta0: Initial pose, shape (3,); zeros if None.
        nu0: Initial velocity, shape (3,); zeros if None. The EKF starts from the
            true state with its configured initial covariance.

    Returns:
        The series at every physics step, N = N_ref * steps_per_command rows.

    Raises:
        StateShapeError: If an input has the wrong shape or is not finite.
    """
    cfg = LowLevelConfig() if config is None else config
    refs_arr = _finite("refs", refs)
    if refs_arr.ndim != 2 or refs_arr.shape[1] != 3 or refs_arr.shape[0] < 1:
        raise StateShapeError(f"refs must have shape (N_ref, 3), got {refs_arr.shape!r}")
    n = refs_arr.shape[0] * cfg.steps_per_command
    e0 = np.zeros(3) if eta0 is None else _finite("eta0", eta0, (3,))
    v0 = np.zeros(3) if nu0 is None else _finite("nu0", nu0, (3,))
    m_inv, coef = cfg.vessel.kernel_arrays()
    mma = MmaArrays.build(cfg.thrusters, replace(cfg.mma, dt_s=cfg.control_period_s))
    b_pinv = (
        mma.b_pinv
        if cfg.allocator is AllocatorKind.MIN_MAGNITUDE_AZIMUTH
        else np.ascontiguousarray(np.linalg.pinv(extended_matrix(mma.tp)))
    )
    b_env = np.ascontiguousarray(cfg.environment.series(n, cfg.dt_s))
    observer = ObserverConfig() if cfg.observer is None else cfg.observer
    ekf = observer.arrays()
    x0 = np.zeros(ekf.x.shape[0])
    x0[0:3] = e0
    x0[3:6] = v0
    obs_init(ekf, 0, x0, observer.initial_covariance())
    # Separate, reproducible streams for the two sensors (not drawn without observer).
    pose_seed, imu_seed = np.random.SeedSequence(cfg.seed).generate_state(2)
    pose_n = n if cfg.observer is not None else 0
    pose = pose_noise_series(cfg.pose_sensor, pose_n, int(pose_seed))
    imu = imu_noise_series(cfg.imu, pose_n, int(imu_seed))
    out = np.empty((n, N_OUT))
    closed_loop_kernel(
        m_inv, coef, cfg.vessel.mass_matrix(), int(cfg.integrator), cfg.dt_s,
        mma.tp, int(cfg.allocator), mma.be, b_pinv, mma.q, mma.cfg, mma.a_ref, mma.weights,
        mma.wq, cfg.gains.as_array(cfg.thrusters), cfg.control_every, cfg.steps_per_command,
        e0, v0, np.ascontiguousarray(refs_arr), b_env, cfg.observer is not None, ekf,
        np.ascontiguousarray(pose.noise), np.ascontiguousarray(pose.available),
        np.zeros((pose.delay_steps + 1, 4)), np.ascontiguousarray(imu.noise),
        np.ascontiguousarray(imu.bias), out,
    )  # fmt: skip
    return unpack(out)


def _finite(name: str, value: object, shape: tuple[int, ...] | None = None) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    if shape is not None and arr.shape != shape:
        raise StateShapeError(f"{name} must have shape {shape!r}, got {arr.shape!r}")
    if not np.all(np.isfinite(arr)):
        raise StateShapeError(f"{name} must be finite")
    return arr
