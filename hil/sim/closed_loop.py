"""The whole low level in one compiled loop: sensors -> EKF -> low level -> vessel.

One ``@njit`` loop at the physics rate (100 Hz by default) built only from the kernels
the vessel runs: the low-level tick of :mod:`hil.controllers.low_level` (the code
behind the runtime's ``LowLevel``), the plant step of :mod:`hil.sim.plant` (the code
behind the simulated world) and the observer's kernels, so a 3-minute run takes a
fraction of a second and there is one copy of the math. Per physics step k
(t = k dt):

1. sensors: pose and IMU samples of the true state, with pre-generated noise;
2. observer: the EKF fuses them (or the true velocity is used, ``observer=None``);
3. every ``control_every`` steps: :func:`~hil.controllers.low_level.low_level_tick`
   on the current reference -> force demand and thruster setpoints, allocated from
   the allocator's own last angles, the PID integrator fed the allocator's achieved
   force at the same tick (the vessel has no thrust or pod-angle feedback);
4. :func:`~hil.sim.plant.plant_step`: thrusters move toward their setpoints within
   their rate limits and the vessel advances one step under thrust plus load.

The reference sequence is held ``command_period_s`` (2 s) per row, as the symbolic
layer issues it. ``tests/sim/test_closed_loop.py`` pins this loop tick for tick to
the runtime's low-level object driving the simulated world.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from hil.controllers.allocation import MmaConfig
from hil.controllers.low_level import (
    AllocatorKind,
    LowLevelArrays,
    LowLevelParams,
    low_level_tick,
)
from hil.controllers.observer import ObserverConfig
from hil.controllers.observer_arrays import EkfArrays
from hil.controllers.observer_imu import obs_imu
from hil.controllers.observer_kernels import obs_init, obs_pose
from hil.controllers.pid import DEFAULT_GAINS, PidGains
from hil.core.arrays import BoolArray, FloatArray
from hil.core.jit import njit
from hil.model.coefficients import ENTERPRISE_I, VesselParams
from hil.model.dynamics import Integrator, acceleration
from hil.model.environment import EnvironmentalLoad
from hil.model.errors import StateShapeError
from hil.model.thrusters import VOYAGER_THRUSTERS, ThrusterParams
from hil.sim.errors import ClosedLoopConfigError
from hil.sim.plant import (
    N_PLANT,
    N_TRACE,
    P_ALPHA,
    P_ETA,
    P_NU,
    P_U,
    TR_ETA,
    TR_NU,
    TR_TAU,
    plant_step,
)
from hil.sim.sensors import (
    ImuSensorConfig,
    PoseSensorConfig,
    imu_noise_series,
    imu_reading,
    pose_noise_series,
    pose_sensor_step,
)


@dataclass(frozen=True)
class LowLevelConfig:
    """Configuration of the simulated low level.

    Attributes:
        vessel: Model coefficients.
        thrusters: Thruster geometry and limits.
        gains: PID gains.
        allocator: Which allocator to run.
        mma: Settings of the minimum-magnitude-and-azimuth allocator (its ``dt_s`` is
            replaced by ``control_period_s``, as on the vessel at 20 Hz).
        environment: Environmental load b(t) (zero by default).
        dt_s: Physics step (s), 0.01 as in the paper.
        integrator: Vessel integrator.
        control_period_s: PID and allocation period (s): 0.05 (20 Hz) by default;
            ``dt_s`` runs them every physics step. Must be a multiple of ``dt_s``.
        command_period_s: How long each reference row is held (s).
        observer: EKF settings; None feeds the PID the true velocity (no sensors).
        pose_sensor: Motion-capture model (its rate must divide 1 / dt_s).
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
        if abs(self.imu.rate_hz * self.dt_s - 1.0) > 1e-9:
            raise ClosedLoopConfigError(
                f"imu.rate_hz must equal 1 / dt_s = {1.0 / self.dt_s!r}, got {self.imu.rate_hz!r}"
            )
        every = 1.0 / (self.pose_sensor.rate_hz * self.dt_s)
        if abs(every - round(every)) > 1e-6 or round(every) < 1:
            raise ClosedLoopConfigError(
                f"pose_sensor.rate_hz must divide 1 / dt_s = {1.0 / self.dt_s!r}, "
                f"got {self.pose_sensor.rate_hz!r}"
            )

    @property
    def pose_every(self) -> int:
        """Physics steps per pose sample."""
        return round(1.0 / (self.pose_sensor.rate_hz * self.dt_s))

    def pose_draws(self) -> PoseSensorConfig:
        """Return the pose sensor drawn per physics step: its noise, outages and delay.

        A slower feed samples every :attr:`pose_every`-th step of these draws; its delay
        is counted in physics steps, not in its own periods.
        """
        return replace(self.pose_sensor, rate_hz=1.0 / self.dt_s)

    @property
    def control_every(self) -> int:
        """Physics steps per control step."""
        return round(self.control_period_s / self.dt_s)

    @property
    def steps_per_command(self) -> int:
        """Physics steps per reference row."""
        return round(self.command_period_s / self.dt_s)

    def low_level(self) -> LowLevelParams:
        """Return the low level this loop runs (the vessel's, at ``control_period_s``)."""
        return LowLevelParams(
            gains=self.gains,
            vessel=self.vessel,
            thrusters=self.thrusters,
            allocator=self.allocator,
            mma=replace(self.mma, dt_s=self.control_period_s),
            dt_s=self.control_period_s,
        )


@dataclass(frozen=True)
class ClosedLoopResult:
    """Time-major series of one closed-loop run, sampled at every physics step.

    Row k is the state at t = k dt (before step k) and what was applied over step k.

    Attributes:
        t_s: Times, shape (N,) (s).
        eta: True pose (x, y, psi), shape (N, 3).
        nu: True body velocity (u, v, r), shape (N, 3).
        nu_hat: Velocity the controller used (estimate), shape (N, 3).
        eta_hat: The EKF's pose estimate at the same instant, shape (N, 3); the true
            pose without an observer.
        nu_ref: Reference in force, shape (N, 3).
        tau_cmd: PID force demand, shape (N, 3) (N, N, N m).
        tau: Thrust actually applied to the hull, shape (N, 3).
        commands: Applied thruster commands (tunnel, port, starboard), shape (N, 3).
        angles_rad: Applied azimuth angles (port, starboard), shape (N, 2).
        setpoints: Commands the low level sent (tunnel, port, starboard), held
            between control ticks, shape (N, 3).
        setpoint_angles_rad: Pod angles the low level sent, shape (N, 2) (rad).
    """

    t_s: FloatArray
    eta: FloatArray
    nu: FloatArray
    nu_hat: FloatArray
    eta_hat: FloatArray
    nu_ref: FloatArray
    tau_cmd: FloatArray
    tau: FloatArray
    commands: FloatArray
    angles_rad: FloatArray
    setpoints: FloatArray
    setpoint_angles_rad: FloatArray


@njit
def closed_loop_kernel(
    m_inv: FloatArray,
    coef: FloatArray,
    method: int,
    dt: float,
    low: LowLevelArrays,
    control_every: int,
    steps_per_ref: int,
    plant0: FloatArray,
    low_state0: FloatArray,
    refs: FloatArray,
    b_env: FloatArray,
    use_observer: bool,
    ekf: EkfArrays,
    pose_noise: FloatArray,
    pose_available: BoolArray,
    pose_ring: FloatArray,
    pose_every: int,
    pose_on_receipt: bool,
    imu_noise: FloatArray,
    imu_bias: FloatArray,
    out: FloatArray,
) -> None:
    """Run the loop and write row k of ``out`` (see :func:`unpack` for the columns).

    Args:
        m_inv: Vessel M^-1, shape (3, 3).
        coef: Vessel coefficient array.
        method: Vessel integrator (:class:`Integrator` value).
        dt: Physics step (s).
        low: The low level's constant arrays (its ``dt`` is the control period).
        control_every: Physics steps per control step.
        steps_per_ref: Physics steps per reference row.
        plant0: Initial plant state, (N_PLANT,) (see :mod:`hil.sim.plant`).
        low_state0: Initial low-level state, (N_LOW_LEVEL_STATE,).
        refs: References, (N_ref, 3).
        b_env: Environmental load per step, (N, 3).
        use_observer: Feed the low level the EKF's velocity (else the true one).
        ekf: Initialized EKF arrays (updated in place).
        pose_noise: Pose noise per step, (N, 3).
        pose_available: Pose availability per step, (N,).
        pose_ring: Pose delay line, (delay + 1, 4), zeros; delay in physics steps.
        pose_every: Physics steps per pose sample (a pose is measured when k is a multiple).
        pose_on_receipt: Stamp each pose with its delivery step (else its measurement step).
        imu_noise: IMU white noise per step, (N, 3).
        imu_bias: IMU bias per step, (N, 3).
        out: Output buffer, (N, N_OUT), N = N_ref * steps_per_ref.
    """
    n = refs.shape[0] * steps_per_ref
    dt_ns = round(dt * 1e9)
    plant = plant0.copy()
    low_state = low_state0.copy()
    trace = np.zeros(N_TRACE)
    u_set = plant[P_U : P_U + 3].copy()
    a_set = plant[P_ALPHA : P_ALPHA + 2].copy()
    tau_cmd, tau = np.zeros(3), np.zeros(3)
    imu_buf, pose_buf = np.zeros(3), np.zeros(3)
    for k in range(n):
        nu_ref = refs[k // steps_per_ref]
        eta = plant[P_ETA : P_ETA + 3]
        nu = plant[P_NU : P_NU + 3]
        if use_observer:
            # Sensors see the state at t_k; the accelerometer the force of the last step.
            nu_dot = acceleration(m_inv, coef, nu, tau + b_env[max(k - 1, 0)])
            imu_reading(nu, nu_dot, imu_noise[k], imu_bias[k], imu_buf)
            obs_imu(ekf, k * dt_ns, imu_buf[0], imu_buf[1], imu_buf[2])
            sampled = pose_available[k] and k % pose_every == 0
            _observe_pose(ekf, pose_ring, k, dt_ns, eta, pose_noise[k], sampled,
                          pose_on_receipt, pose_buf)
            nu_hat = ekf.x[3:6].copy()
            eta_hat = ekf.x[0:3].copy()
        else:
            nu_hat = nu.copy()
            eta_hat = eta.copy()
        if k % control_every == 0:
            tau_cmd, u_set, a_set, _, low_state = low_level_tick(low, low_state, nu_ref, nu_hat)
        plant_step(m_inv, coef, low.tp, method, dt, plant, u_set, a_set, b_env[k], trace)
        tau[:] = trace[TR_TAU : TR_TAU + 3]
        _write_row(out, k, k * dt, trace, plant, nu_hat, eta_hat, nu_ref, tau_cmd, u_set, a_set)


@njit
def _observe_pose(
    ekf: EkfArrays,
    pose_ring: FloatArray,
    k: int,
    dt_ns: int,
    eta: FloatArray,
    noise: FloatArray,
    sampled: bool,
    on_receipt: bool,
    pose_buf: FloatArray,
) -> None:
    """Pass step k's pose sensor (delay line) and feed a delivered pose to the EKF.

    Stamped with its delivery step when `on_receipt` (a driver stamping on receipt), else
    with its measurement step.
    """
    k_meas = pose_sensor_step(pose_ring, k, eta, noise, sampled, pose_buf)
    if k_meas >= 0:
        k_stamp = k if on_receipt else k_meas
        obs_pose(ekf, k_stamp * dt_ns, pose_buf[0], pose_buf[1], pose_buf[2])


@njit
def _write_row(
    out: FloatArray,
    k: int,
    t_s: float,
    trace: FloatArray,
    plant: FloatArray,
    nu_hat: FloatArray,
    eta_hat: FloatArray,
    nu_ref: FloatArray,
    tau_cmd: FloatArray,
    u_set: FloatArray,
    a_set: FloatArray,
) -> None:
    """Write row k of the output (N, N_OUT): the columns :func:`unpack` reads."""
    row = out[k]
    row[0] = t_s
    row[1:4] = trace[TR_ETA : TR_ETA + 3]
    row[4:7] = trace[TR_NU : TR_NU + 3]
    row[7:10] = nu_hat
    row[10:13] = nu_ref
    row[13:16] = tau_cmd
    row[16:19] = trace[TR_TAU : TR_TAU + 3]
    row[19:22] = plant[P_U : P_U + 3]
    row[22:24] = plant[P_ALPHA : P_ALPHA + 2]
    row[24:27] = u_set
    row[27:29] = a_set
    row[29:32] = eta_hat

N_OUT = 32


def unpack(out: FloatArray) -> ClosedLoopResult:
    """Split the kernel's (N, N_OUT) buffer into a :class:`ClosedLoopResult`."""
    return ClosedLoopResult(
        t_s=out[:, 0].copy(),
        eta=out[:, 1:4].copy(),
        nu=out[:, 4:7].copy(),
        nu_hat=out[:, 7:10].copy(),
        eta_hat=out[:, 29:32].copy(),
        nu_ref=out[:, 10:13].copy(),
        tau_cmd=out[:, 13:16].copy(),
        tau=out[:, 16:19].copy(),
        commands=out[:, 19:22].copy(),
        angles_rad=out[:, 22:24].copy(),
        setpoints=out[:, 24:27].copy(),
        setpoint_angles_rad=out[:, 27:29].copy(),
    )


def initial_plant(low_level: LowLevelParams, eta0: FloatArray, nu0: FloatArray) -> FloatArray:
    """Return the plant state at the start, (N_PLANT,): thrusters idle at the pods' hold."""
    plant = np.zeros(N_PLANT)
    plant[P_ETA : P_ETA + 3] = eta0
    plant[P_NU : P_NU + 3] = nu0
    plant[P_ALPHA : P_ALPHA + 2] = low_level.mma.reference_angles_rad
    return plant


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
    low_level = cfg.low_level()
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
    pose = pose_noise_series(cfg.pose_draws(), pose_n, int(pose_seed))
    imu = imu_noise_series(cfg.imu, pose_n, int(imu_seed))
    out = np.empty((n, N_OUT))
    closed_loop_kernel(
        m_inv, coef, int(cfg.integrator), cfg.dt_s, low_level.arrays(), cfg.control_every,
        cfg.steps_per_command, initial_plant(low_level, e0, v0), low_level.initial_state(),
        np.ascontiguousarray(refs_arr), b_env, cfg.observer is not None, ekf,
        np.ascontiguousarray(pose.noise), np.ascontiguousarray(pose.available),
        np.zeros((pose.delay_steps + 1, 4)), cfg.pose_every, cfg.pose_sensor.stamped_on_receipt,
        np.ascontiguousarray(imu.noise),
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
