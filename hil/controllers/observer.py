"""State observer: an EKF over (eta, nu) fusing Qualisys pose and the IMU.

:class:`Ekf` is the Python face of the compiled kernels in
:mod:`hil.controllers.observer_kernels`: it takes :class:`PoseSample` and
:class:`ImuSample` objects, keeps the kernels' arrays and reports the estimate
and counters. It does no arithmetic of its own, so the closed-loop simulation,
which calls the same kernels from compiled code, sees the same numbers.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from hil.controllers.errors import (
    ObserverConfigError,
    ObserverInputError,
    ObserverNotInitializedError,
)
from hil.controllers.observer_arrays import (
    C_POSE_FUSED,
    S_ABSURD,
    S_DUPLICATE,
    S_FUSED,
    S_GATED,
    S_NONFINITE,
    S_NOT_INITIALIZED,
    S_RESET,
    S_TOO_OLD,
    EkfArrays,
    allocate_arrays,
)
from hil.controllers.observer_imu import obs_imu
from hil.controllers.observer_kernels import obs_init, obs_pose, obs_predicted, obs_time_ns
from hil.controllers.observer_math import (
    I_BAX,
    I_BR,
    I_R,
    I_U,
    N_PARAMS,
    N_STATE,
    P_ACCEL_HOLD,
    P_GATE_GYRO,
    P_GATE_POSE,
    P_GATE_RESET,
    P_MAX_ACC,
    P_MAX_DELAY,
    P_MAX_POS,
    P_MAX_RATE,
    P_Q_BA,
    P_Q_BR,
    P_Q_R,
    P_Q_UV,
    P_R_GYRO,
    P_R_PSI,
    P_R_X,
    P_R_Y,
    P_RESTART_VAR_BA,
    P_RESTART_VAR_BR,
    P_RESTART_VAR_R,
    P_RESTART_VAR_UV,
)
from hil.controllers.observer_ring import M_INIT
from hil.core.arrays import FloatArray
from hil.core.samples import Frame, ImuSample, PoseSample, SampleError

__all__ = [
    "Ekf",
    "ObserverConfig",
    "ObserverCounters",
    "ObserverEstimate",
    "ObserverStatus",
    "PoseInnovation",
]


class ObserverStatus(enum.IntEnum):
    """What became of one sample (the kernels' ``S_*`` codes)."""

    FUSED = S_FUSED
    NONFINITE = S_NONFINITE
    ABSURD = S_ABSURD
    GATED = S_GATED
    TOO_OLD = S_TOO_OLD
    DUPLICATE = S_DUPLICATE
    NOT_INITIALIZED = S_NOT_INITIALIZED
    RESET = S_RESET


@dataclass(frozen=True, slots=True)
class ObserverConfig:
    """Noise model, gates and limits of the EKF.

    Defaults: Qualisys pose noise (about 1 mm, 0.1 deg) and a BNO055 IMU at
    100 Hz (accelerometer 150 ug/sqrt(Hz) -> about 0.012 m/s^2 per sample,
    gyro 0.014 deg/s/sqrt(Hz) -> about 0.0017 rad/s per sample, BNO055
    datasheet, accelerometer and gyroscope noise density).

    Attributes:
        pose_std_m: Standard deviation of a pose's x and y (m), > 0.
        pose_yaw_std_rad: Standard deviation of a pose's heading (rad), > 0.
        gyro_std_radps: Standard deviation of one yaw-rate sample (rad/s), > 0.
        accel_std_mps2: Standard deviation of one accelerometer sample (m/s^2), > 0.
        imu_rate_hz: Nominal IMU rate (Hz), > 0; turns accel_std into an intensity.
        velocity_walk_mps_per_sqrt_s: Extra velocity random walk for what the
            accelerometer misses (tilt, vibration) (m/s/sqrt(s)), >= 0.
        yaw_rate_walk_radps_per_sqrt_s: Yaw-rate random walk (rad/s/sqrt(s)), > 0:
            r has no measured derivative, so this is its process model.
        accel_bias_walk_mps2_per_sqrt_s: Accelerometer-bias random walk, >= 0.
        gyro_bias_walk_radps_per_sqrt_s: Gyro-bias random walk, >= 0.
        estimate_bias: Estimate the IMU biases (False freezes them at zero).
        init_velocity_std_mps: Initial standard deviation of u and v (m/s), > 0.
        init_yaw_rate_std_radps: Initial standard deviation of r (rad/s), > 0.
        init_accel_bias_std_mps2: Initial accelerometer-bias std (m/s^2), > 0.
        init_gyro_bias_std_radps: Initial gyro-bias std (rad/s), > 0.
        gate_pose_chi2: Pose gate on d^2 (3 dof; 16.27 keeps 99.9 %), > 0.
        gate_gyro_chi2: Yaw-rate gate on d^2 (1 dof; 10.83 keeps 99.9 %), > 0.
        max_abs_position_m: A pose farther out in x or y is absurd (m), > 0.
        max_abs_accel_mps2: Accelerometer range (m/s^2; BNO055 default +-4 g), > 0.
        max_abs_yaw_rate_radps: Gyro range (rad/s; BNO055 +-2000 deg/s), > 0.
        max_delay_s: Oldest sample fused, before the filter time (s), > 0.
        accel_hold_s: Longest span one accelerometer sample drives the prediction
            (s), > 0; if the IMU falls silent, the velocity is then held constant
            instead of being pushed by a stale reading.
        history_len: Ring slots for late samples (>= 2); one per distinct stamp,
            so 128 keeps over 0.6 s of 100 Hz pose and IMU at different stamps.
        reset_after_gated_poses: After this many gated poses in a row (0.1 s at
            100 Hz) restart the filter from the last one (>= 0; 0: never): eta
            from the pose, P back to the pose noise and the ``init_*`` stds. A
            filter whose prediction went wrong (an accelerometer-bias jump from
            tilt) would otherwise refuse every pose and run away.
    """

    pose_std_m: float = 0.001
    pose_yaw_std_rad: float = math.radians(0.1)
    gyro_std_radps: float = 0.0017
    accel_std_mps2: float = 0.012
    imu_rate_hz: float = 100.0
    velocity_walk_mps_per_sqrt_s: float = 0.005
    yaw_rate_walk_radps_per_sqrt_s: float = 0.2
    accel_bias_walk_mps2_per_sqrt_s: float = 0.001
    gyro_bias_walk_radps_per_sqrt_s: float = 1e-4
    estimate_bias: bool = True
    init_velocity_std_mps: float = 0.1
    init_yaw_rate_std_radps: float = 0.1
    init_accel_bias_std_mps2: float = 0.1
    init_gyro_bias_std_radps: float = 0.02
    gate_pose_chi2: float = 16.27
    gate_gyro_chi2: float = 10.83
    max_abs_position_m: float = 100.0
    max_abs_accel_mps2: float = 40.0
    max_abs_yaw_rate_radps: float = 35.0
    max_delay_s: float = 0.5
    accel_hold_s: float = 0.1
    history_len: int = 128
    reset_after_gated_poses: int = 10

    def __post_init__(self) -> None:
        positive = (
            "pose_std_m",
            "pose_yaw_std_rad",
            "gyro_std_radps",
            "accel_std_mps2",
            "imu_rate_hz",
            "yaw_rate_walk_radps_per_sqrt_s",
            "init_velocity_std_mps",
            "init_yaw_rate_std_radps",
            "init_accel_bias_std_mps2",
            "init_gyro_bias_std_radps",
            "gate_pose_chi2",
            "gate_gyro_chi2",
            "max_abs_position_m",
            "max_abs_accel_mps2",
            "max_abs_yaw_rate_radps",
            "max_delay_s",
            "accel_hold_s",
        )
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ObserverConfigError(f"{name} must be finite and > 0, got {value!r}")
        non_negative = (
            "velocity_walk_mps_per_sqrt_s",
            "accel_bias_walk_mps2_per_sqrt_s",
            "gyro_bias_walk_radps_per_sqrt_s",
        )
        for name in non_negative:
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ObserverConfigError(f"{name} must be finite and >= 0, got {value!r}")
        if isinstance(self.history_len, bool) or not isinstance(self.history_len, int):
            raise ObserverConfigError(f"history_len must be an int, got {self.history_len!r}")
        if self.history_len < 2:
            raise ObserverConfigError(f"history_len must be >= 2, got {self.history_len!r}")
        reset = self.reset_after_gated_poses
        if isinstance(reset, bool) or not isinstance(reset, int) or reset < 0:
            raise ObserverConfigError(f"reset_after_gated_poses must be an int >= 0, got {reset!r}")

    def params(self) -> FloatArray:
        """Return the kernels' parameter vector, shape (N_PARAMS,), ``P_*`` indexing.

        Intensities: q_uv = accel_std^2 / imu_rate + velocity_walk^2 ((m/s)^2/s),
        so that one IMU period adds accel_std^2 dt^2 to the velocity variance, the
        variance a held noisy sample puts there; the walks square to (unit)^2/s.
        """
        p = np.zeros(N_PARAMS)
        p[P_Q_UV] = (
            self.accel_std_mps2**2 / self.imu_rate_hz + self.velocity_walk_mps_per_sqrt_s**2
        )
        p[P_Q_R] = self.yaw_rate_walk_radps_per_sqrt_s**2
        if self.estimate_bias:
            p[P_Q_BA] = self.accel_bias_walk_mps2_per_sqrt_s**2
            p[P_Q_BR] = self.gyro_bias_walk_radps_per_sqrt_s**2
        p[P_R_X] = self.pose_std_m**2
        p[P_R_Y] = self.pose_std_m**2
        p[P_R_PSI] = self.pose_yaw_std_rad**2
        p[P_R_GYRO] = self.gyro_std_radps**2
        p[P_GATE_POSE] = self.gate_pose_chi2
        p[P_GATE_GYRO] = self.gate_gyro_chi2
        p[P_MAX_POS] = self.max_abs_position_m
        p[P_MAX_ACC] = self.max_abs_accel_mps2
        p[P_MAX_RATE] = self.max_abs_yaw_rate_radps
        p[P_MAX_DELAY] = self.max_delay_s
        p[P_GATE_RESET] = float(self.reset_after_gated_poses)
        P0 = np.diag(self.initial_covariance())
        p[P_RESTART_VAR_UV] = P0[I_U]
        p[P_RESTART_VAR_R] = P0[I_R]
        p[P_RESTART_VAR_BA] = P0[I_BAX]
        p[P_RESTART_VAR_BR] = P0[I_BR]
        p[P_ACCEL_HOLD] = self.accel_hold_s
        return p

    def initial_covariance(self) -> FloatArray:
        """Return P0, shape (9, 9): the pose noise on eta, the ``init_*`` stds elsewhere."""
        ba = self.init_accel_bias_std_mps2 if self.estimate_bias else 0.0
        br = self.init_gyro_bias_std_radps if self.estimate_bias else 0.0
        std = np.array(
            [
                self.pose_std_m,
                self.pose_std_m,
                self.pose_yaw_std_rad,
                self.init_velocity_std_mps,
                self.init_velocity_std_mps,
                self.init_yaw_rate_std_radps,
                ba,
                ba,
                br,
            ]
        )
        return np.diag(std**2)

    def arrays(self) -> EkfArrays:
        """Allocate the kernels' arrays for this configuration (not yet initialized)."""
        return allocate_arrays(self.params(), self.history_len)


@dataclass(frozen=True, slots=True)
class ObserverEstimate:
    """The observer's estimate at one time, with its covariance and the IMU biases.

    Not the recorded :class:`hil.core.records.StateEstimate` (pose and velocity
    only, as the bag stores it); the runtime turns one into the other.

    Attributes:
        t_ns: Filter time (ns): the stamp of the newest sample fused.
        eta: Pose (x_m, y_m, psi_rad), shape (3,), arena frame.
        nu: Body velocities (u_mps, v_mps, r_radps), shape (3,).
        bias: IMU biases (b_ax_mps2, b_ay_mps2, b_r_radps), shape (3,).
        covariance: Covariance of (eta, nu), shape (6, 6).
        full_covariance: Covariance of the full state (eta, nu, bias), shape (9, 9).
    """

    t_ns: int
    eta: FloatArray
    nu: FloatArray
    bias: FloatArray
    covariance: FloatArray
    full_covariance: FloatArray


@dataclass(frozen=True, slots=True)
class PoseInnovation:
    """One pose against the filter's prior at its stamp (what its gate judged).

    Attributes:
        nis: Normalized innovation squared y^T S^-1 y (chi-square, 3 dof, for a
            consistent filter; the gate refuses above ``gate_pose_chi2``); NaN when the
            pose was refused before its gate, inf when S was not positive definite.
        position_m: |(z - x_hat, z - y_hat)| (m).
        heading_rad: |z_psi - psi_hat| (rad, wrapped).
    """

    nis: float
    position_m: float
    heading_rad: float


@dataclass(frozen=True, slots=True)
class ObserverCounters:
    """How many samples the observer fused and refused, by reason."""

    pose_fused: int
    pose_late: int
    pose_nonfinite: int
    pose_absurd: int
    pose_gated: int
    pose_too_old: int
    pose_duplicate: int
    imu_fused: int
    imu_late: int
    imu_nonfinite: int
    imu_absurd: int
    gyro_gated: int
    imu_too_old: int
    imu_duplicate: int
    not_initialized: int
    pose_reset: int

    @property
    def rejected(self) -> int:
        """Return the number of samples refused outright (gated yaw rates excluded)."""
        return (
            self.pose_nonfinite
            + self.pose_absurd
            + self.pose_gated
            + self.pose_too_old
            + self.pose_duplicate
            + self.imu_nonfinite
            + self.imu_absurd
            + self.imu_too_old
            + self.imu_duplicate
            + self.not_initialized
        )


class Ekf:
    """Extended Kalman filter over (eta, nu, IMU bias), fed sample by sample.

    The filter starts at the first usable pose (eta from the pose, nu and bias
    zero, P0 from the config), as robot_localization does, or at an explicit
    :meth:`initialize`. IMU samples advance the filter time and set the held
    acceleration input; poses and yaw rates are measurements. A sample stamped
    before the filter time is fused at its stamp and the filter re-run forward
    (see ``obs_pose``); non-finite, out-of-range, duplicate, too old and gated
    samples are refused without touching the estimate and counted. After
    ``reset_after_gated_poses`` gated poses in a row the filter restarts from
    the pose.

    Args:
        config: Noise model and limits; the defaults fit Qualisys + BNO055.

    Notes:
        Process model, with the accelerometer's specific force f as input and
        x = (eta, nu, b_ax, b_ay, b_r) (Fossen 2021, Ch. 2 and 14):

            eta_dot = R(psi) nu
            u_dot = f_x - b_ax + r v,   v_dot = f_y - b_ay - r u,
            r_dot = w_r,   b_dot = w_b,

        forward Euler, F = I + dt J, P <- F P F^T + Q dt (Moore & Stouch 2014).
        Pose z = eta + v (heading innovation wrapped), gyro z = r + b_r + v;
        chi-square gate on y^T S^-1 y, then the EKF update (Simon 2006, Ch. 13);
        details in :mod:`hil.controllers.observer_math`. The specific force as a
        known input, rather than robot_localization's constant-velocity random
        walk, is the aided-INS choice: with 1 mm poses at 100 Hz the velocity
        follows thrust changes without the lag of a random-walk model, and the
        accelerometer bias, which would otherwise leave a velocity offset of
        about sqrt(2) b / omega_n, is estimated as a state.
    """

    def __init__(self, config: ObserverConfig | None = None) -> None:
        self._config = config if config is not None else ObserverConfig()
        self._a = self._config.arrays()

    @property
    def config(self) -> ObserverConfig:
        """Return the configuration."""
        return self._config

    @property
    def arrays(self) -> EkfArrays:
        """Return the kernels' arrays (live; for compiled callers and inspection)."""
        return self._a

    @property
    def initialized(self) -> bool:
        """Return whether the filter has started."""
        return bool(self._a.meta[M_INIT])

    @property
    def time_ns(self) -> int | None:
        """Return the filter time (ns), or None before it starts."""
        return int(obs_time_ns(self._a)) if self.initialized else None

    def initialize(
        self,
        t_ns: int,
        eta: FloatArray,
        nu: FloatArray | None = None,
        covariance: FloatArray | None = None,
    ) -> None:
        """Start (or restart) the filter at `t_ns`; the counters are kept.

        Args:
            t_ns: Start time (ns).
            eta: Pose (x_m, y_m, psi_rad), shape (3,).
            nu: Body velocities (u, v, r), shape (3,); zero if None.
            covariance: Full P0, shape (9, 9); the config's if None.

        Raises:
            ObserverInputError: A shape is wrong or a value is not finite.
        """
        x0 = np.zeros(N_STATE)
        x0[0:3] = _vector("eta", eta, 3)
        if nu is not None:
            x0[3:6] = _vector("nu", nu, 3)
        P0 = self._config.initial_covariance() if covariance is None else np.asarray(covariance)
        if P0.shape != (N_STATE, N_STATE) or not np.all(np.isfinite(P0)):
            raise ObserverInputError(f"covariance must be finite (9, 9), got {P0!r}")
        obs_init(self._a, int(t_ns), x0, np.array(P0, dtype=np.float64))

    def process_pose(self, sample: PoseSample) -> ObserverStatus:
        """Fuse a pose sample (arena frame); start the filter with it if needed.

        Raises:
            ObserverInputError: The sample is not in the arena frame.
        """
        try:
            eta = sample.eta(Frame.ARENA)
        except SampleError as err:
            raise ObserverInputError(f"observer needs arena-frame poses: {err}") from err
        return self.fuse_pose(sample.t_ns, float(eta[0]), float(eta[1]), float(eta[2]))

    def process_imu(self, sample: ImuSample) -> ObserverStatus:
        """Take an IMU sample (body frame)."""
        return self.fuse_imu(
            sample.t_ns, sample.accel_x_mps2, sample.accel_y_mps2, sample.yaw_rate_radps
        )

    def fuse_pose(self, t_ns: int, x_m: float, y_m: float, yaw_rad: float) -> ObserverStatus:
        """Fuse raw pose values (possibly NaN, absurd, late); see ``obs_pose``."""
        if not self.initialized and math.isfinite(x_m + y_m + yaw_rad):
            limit = self._config.max_abs_position_m
            if abs(x_m) <= limit and abs(y_m) <= limit:
                self.initialize(t_ns, np.array([x_m, y_m, yaw_rad]))
                # The start itself is the fused pose (no prior: no innovation).
                self._a.counters[C_POSE_FUSED] += 1
                self._a.innovation[:] = np.nan
                return ObserverStatus.FUSED
        return ObserverStatus(obs_pose(self._a, int(t_ns), x_m, y_m, yaw_rad))

    def fuse_imu(
        self, t_ns: int, accel_x_mps2: float, accel_y_mps2: float, yaw_rate_radps: float
    ) -> ObserverStatus:
        """Take raw IMU values (possibly NaN, absurd, late); see ``obs_imu``."""
        return ObserverStatus(
            obs_imu(self._a, int(t_ns), accel_x_mps2, accel_y_mps2, yaw_rate_radps)
        )

    def estimate(self) -> ObserverEstimate:
        """Return the estimate at the filter time (copies).

        Raises:
            ObserverNotInitializedError: No pose or explicit start yet.
        """
        if not self.initialized:
            raise ObserverNotInitializedError("no pose has been fused yet")
        return _estimate(int(obs_time_ns(self._a)), self._a.x.copy(), self._a.P.copy())

    def predicted(self, t_ns: int) -> ObserverEstimate:
        """Return the estimate extrapolated to `t_ns` (>= the filter time); change nothing.

        Raises:
            ObserverNotInitializedError: No pose or explicit start yet.
            ObserverInputError: `t_ns` is before the filter time.
        """
        if not self.initialized:
            raise ObserverNotInitializedError("no pose has been fused yet")
        x = np.empty(N_STATE)
        P = np.empty((N_STATE, N_STATE))
        if not obs_predicted(self._a, int(t_ns), x, P):
            raise ObserverInputError(
                f"cannot predict back to t_ns={t_ns!r}: the filter is at {self.time_ns!r}"
            )
        return _estimate(int(t_ns), x, P)

    def last_innovation(self) -> PoseInnovation:
        """Return the innovation of the last pose against its prior (NaN: none computed)."""
        nis, position_m, heading_rad = (float(v) for v in self._a.innovation)
        return PoseInnovation(nis, position_m, heading_rad)

    def counters(self) -> ObserverCounters:
        """Return the sample counters so far."""
        return ObserverCounters(*(int(v) for v in self._a.counters))


def _estimate(t_ns: int, x: FloatArray, P: FloatArray) -> ObserverEstimate:
    return ObserverEstimate(
        t_ns=t_ns,
        eta=x[0:3],
        nu=x[3:6],
        bias=x[6:9],
        covariance=P[0:6, 0:6].copy(),
        full_covariance=P,
    )


def _vector(name: str, value: FloatArray, n: int) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise ObserverInputError(f"{name} must be finite with shape ({n},), got {value!r}")
    return arr
