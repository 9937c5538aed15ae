"""Simulated sensors: Qualisys pose and BNO055-like IMU, seeded and reproducible.

Two forms that give the same numbers for the same seed:

* For compiled loops: :func:`pose_noise_series` and :func:`imu_noise_series`
  draw every random number of an N-step run up front, and the kernels
  :func:`pose_sensor_step`, :func:`imu_reading` and :func:`specific_force` turn
  the true state into readings with them.
* For the runtime: :class:`SimulatedPoseSensor` and :class:`SimulatedImu` turn the
  true state at time ``t_ns`` into :class:`PoseSample` / :class:`ImuSample`
  objects, drawing the same streams block by block and calling the same kernels.

Each sensor is sampled once per call (one call per sample period, 1 / rate_hz).
A pose measured at step k is stamped with step k's time and delivered at step
k + round(latency_s * rate_hz), unless step k lies in a dropout.

Notes:
    IMU model (Farrell 2008, Ch. 4; Fossen 2021, Ch. 14): the accelerometer
    reads the body-frame specific force of planar motion,

        f = nu_dot[0:2] + (-r v, r u),

    (gravity is along body z and dropped), the gyro reads r; each channel adds
    white noise and a bias b_k = b_0 + sum_{i<k} sigma_w sqrt(dt) w_i (constant
    plus random walk). Default noise: BNO055 datasheet (accelerometer
    150 ug/sqrt(Hz), gyro 0.014 deg/s/sqrt(Hz), over its 62.5 Hz / 47 Hz
    bandwidth); Qualisys pose about 1 mm and 0.1 deg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from hil.core.arrays import BoolArray, FloatArray
from hil.core.geometry import wrap_angle
from hil.core.jit import njit
from hil.core.pose_feeds import PoseFeed
from hil.core.samples import Frame, ImuSample, PoseSample
from hil.model.errors import SimError, StateShapeError

__all__ = [
    "ImuNoise",
    "ImuSensorConfig",
    "PoseNoise",
    "PoseSensorConfig",
    "SensorConfigError",
    "SimulatedImu",
    "SimulatedPoseSensor",
    "imu_noise_series",
    "imu_reading",
    "pose_noise_series",
    "pose_sensor_for",
    "pose_sensor_step",
    "specific_force",
]

_BLOCK = 1024  # steps drawn at a time by the runtime sensors


class SensorConfigError(SimError, ValueError):
    """A sensor configuration with a negative, non-finite or inconsistent value."""


def _vector3(name: str, value: FloatArray) -> FloatArray:
    arr = np.ascontiguousarray(value, dtype=np.float64)
    if arr.shape != (3,):
        raise StateShapeError(f"{name} must have shape (3,), got {arr.shape!r}")
    return arr


def _check(name: str, value: float, *, positive: bool) -> None:
    ok = math.isfinite(value) and (value > 0.0 if positive else value >= 0.0)
    if not ok:
        bound = "> 0" if positive else ">= 0"
        raise SensorConfigError(f"{name} must be finite and {bound}, got {value!r}")


@dataclass(frozen=True, slots=True)
class PoseSensorConfig:
    """Motion-capture pose sensor.

    Attributes:
        rate_hz: Sample rate (Hz), > 0.
        noise_std_x_m: White noise on x (m), >= 0.
        noise_std_y_m: White noise on y (m), >= 0.
        noise_std_yaw_rad: White noise on the heading (rad), >= 0.
        latency_s: Delivery delay (s), >= 0, rounded to whole sample periods.
        dropout_rate_hz: Mean number of random outages starting per second, >= 0.
        dropout_duration_s: Length of each random outage (s), >= 0, rounded to periods.
        scheduled_dropouts_s: Extra outages as (start_s, duration_s) after the
            first sample; samples measured in [start, start + duration) are lost.
        stamped_on_receipt: Stamp each pose with its delivery time instead of its
            measurement time (a driver that stamps on receipt, as mocap4ros2_qualisys
            does): the stamp is then ``latency_s`` late, a delay the EKF cannot see.
    """

    rate_hz: float = 100.0
    noise_std_x_m: float = 0.001
    noise_std_y_m: float = 0.001
    noise_std_yaw_rad: float = math.radians(0.1)
    latency_s: float = 0.01
    dropout_rate_hz: float = 0.0
    dropout_duration_s: float = 1.0
    scheduled_dropouts_s: tuple[tuple[float, float], ...] = ()
    stamped_on_receipt: bool = False

    def __post_init__(self) -> None:
        _check("rate_hz", self.rate_hz, positive=True)
        for name in (
            "noise_std_x_m",
            "noise_std_y_m",
            "noise_std_yaw_rad",
            "latency_s",
            "dropout_rate_hz",
            "dropout_duration_s",
        ):
            _check(name, getattr(self, name), positive=False)
        if self.dropout_rate_hz >= self.rate_hz:
            raise SensorConfigError(
                f"dropout_rate_hz must be below rate_hz {self.rate_hz!r}, "
                f"got {self.dropout_rate_hz!r}"
            )
        for window in self.scheduled_dropouts_s:
            if len(window) != 2:
                raise SensorConfigError(
                    f"a scheduled dropout is (start_s, duration_s), got {window!r}"
                )
            _check("scheduled dropout start", window[0], positive=False)
            _check("scheduled dropout duration", window[1], positive=False)

    @property
    def delay_steps(self) -> int:
        """Return the latency in whole sample periods."""
        return round(self.latency_s * self.rate_hz)

    @property
    def dropout_steps(self) -> int:
        """Return the length of one random outage in sample periods."""
        return round(self.dropout_duration_s * self.rate_hz)

    def expected_dropout_fraction(self) -> float:
        """Return the long-run fraction of samples lost to random outages.

        A free step starts an outage of L steps with probability p = rate / f_s,
        so free runs last (1 - p) / p steps on average: fraction p L / (1 - p + p L).
        """
        p = self.dropout_rate_hz / self.rate_hz
        n = self.dropout_steps
        return p * n / (1.0 - p + p * n)


def pose_sensor_for(feed: PoseFeed, base: PoseSensorConfig | None = None) -> PoseSensorConfig:
    """Return the simulated sensor that gives `feed`: its rate, delay and stamping.

    Args:
        feed: The named pose feed (:mod:`hil.core.pose_feeds`).
        base: Noise and outages to keep (default: :class:`PoseSensorConfig`'s).
    """
    return replace(PoseSensorConfig() if base is None else base, rate_hz=feed.rate_hz,
                   latency_s=feed.delay_s, stamped_on_receipt=not feed.stamped_at_capture)


@dataclass(frozen=True, slots=True)
class ImuSensorConfig:
    """Planar IMU: accelerometer x, y and gyro z, each with noise and bias.

    Attributes:
        rate_hz: Sample rate (Hz), > 0.
        accel_noise_std_mps2: White noise per accelerometer sample (m/s^2), >= 0.
        gyro_noise_std_radps: White noise per gyro sample (rad/s), >= 0.
        accel_bias_mps2: Constant accelerometer bias (x, y) (m/s^2), finite.
        gyro_bias_radps: Constant gyro bias (rad/s), finite.
        accel_bias_walk_mps2_per_sqrt_s: Accelerometer-bias random walk, >= 0.
        gyro_bias_walk_radps_per_sqrt_s: Gyro-bias random walk, >= 0.
    """

    rate_hz: float = 100.0
    accel_noise_std_mps2: float = 0.012
    gyro_noise_std_radps: float = 0.0017
    accel_bias_mps2: tuple[float, float] = (0.03, -0.02)
    gyro_bias_radps: float = 0.003
    accel_bias_walk_mps2_per_sqrt_s: float = 0.001
    gyro_bias_walk_radps_per_sqrt_s: float = 1e-4

    def __post_init__(self) -> None:
        _check("rate_hz", self.rate_hz, positive=True)
        for name in (
            "accel_noise_std_mps2",
            "gyro_noise_std_radps",
            "accel_bias_walk_mps2_per_sqrt_s",
            "gyro_bias_walk_radps_per_sqrt_s",
        ):
            _check(name, getattr(self, name), positive=False)
        values = (*self.accel_bias_mps2, self.gyro_bias_radps)
        if len(self.accel_bias_mps2) != 2 or not all(math.isfinite(v) for v in values):
            raise SensorConfigError(f"IMU biases must be finite (x, y) and z, got {values!r}")


class PoseNoise(NamedTuple):
    """Random draws of a pose sensor for N steps.

    Attributes:
        noise: Additive noise on (x_m, y_m, psi_rad) of the pose measured at step
            k, shape (N, 3), time-major.
        available: False where the pose measured at step k is lost, shape (N,).
        delay_steps: Steps between measuring a pose and delivering it.
    """

    noise: FloatArray
    available: BoolArray
    delay_steps: int


class ImuNoise(NamedTuple):
    """Random draws of an IMU for N steps.

    Attributes:
        noise: White noise on (f_x, f_y, r) at step k, shape (N, 3).
        bias: Bias on (f_x, f_y, r) at step k, shape (N, 3).
    """

    noise: FloatArray
    bias: FloatArray


class _PoseStream:
    """Draws a pose sensor's noise and outages block by block, same result as all at once."""

    def __init__(self, config: PoseSensorConfig, seed: int) -> None:
        noise_seq, dropout_seq = np.random.SeedSequence(seed).spawn(2)
        self._config = config
        self._std = np.array([config.noise_std_x_m, config.noise_std_y_m, config.noise_std_yaw_rad])
        self._noise_rng = np.random.default_rng(noise_seq)
        self._dropout_rng = np.random.default_rng(dropout_seq)
        self._p_start = config.dropout_rate_hz / config.rate_hz
        self._outage_left = 0
        self._step = 0

    def draw(self, n: int) -> tuple[FloatArray, BoolArray]:
        noise = self._noise_rng.standard_normal((n, 3)) * self._std
        starts = self._dropout_rng.random(n) < self._p_start
        available = np.ones(n, dtype=np.bool_)
        length = self._config.dropout_steps
        left = self._outage_left
        for i in range(n):
            if left == 0 and starts[i]:
                left = length
            if left > 0:
                available[i] = False
                left -= 1
        self._outage_left = left
        t_s = (self._step + np.arange(n)) / self._config.rate_hz
        for start, duration in self._config.scheduled_dropouts_s:
            available &= ~((t_s >= start) & (t_s < start + duration))
        self._step += n
        return noise, available


class _ImuStream:
    """Draws an IMU's noise and bias block by block, same result as all at once."""

    def __init__(self, config: ImuSensorConfig, seed: int) -> None:
        noise_seq, walk_seq = np.random.SeedSequence(seed).spawn(2)
        self._noise_rng = np.random.default_rng(noise_seq)
        self._walk_rng = np.random.default_rng(walk_seq)
        self._std = np.array(
            [config.accel_noise_std_mps2, config.accel_noise_std_mps2, config.gyro_noise_std_radps]
        )
        sqrt_dt = math.sqrt(1.0 / config.rate_hz)
        self._walk_std = sqrt_dt * np.array(
            [
                config.accel_bias_walk_mps2_per_sqrt_s,
                config.accel_bias_walk_mps2_per_sqrt_s,
                config.gyro_bias_walk_radps_per_sqrt_s,
            ]
        )
        self._bias = np.array([*config.accel_bias_mps2, config.gyro_bias_radps], dtype=np.float64)

    def draw(self, n: int) -> tuple[FloatArray, FloatArray]:
        noise = self._noise_rng.standard_normal((n, 3)) * self._std
        steps = self._walk_rng.standard_normal((n, 3)) * self._walk_std
        # b_k = b_0 + sum of the steps before k; the carry is the next b.
        walk = np.cumsum(steps, axis=0)
        bias = self._bias + np.vstack([np.zeros((1, 3)), walk[:-1]])[:n]
        if n > 0:
            self._bias = self._bias + walk[-1]
        return noise, bias


def pose_noise_series(config: PoseSensorConfig, n_steps: int, seed: int) -> PoseNoise:
    """Draw every random number a pose sensor uses in an `n_steps` run.

    Args:
        config: The sensor.
        n_steps: Steps N (>= 0), one per sample period.
        seed: Seed of the run; the same seed gives the same arrays.

    Returns:
        Noise (N, 3), availability (N,) and the delay in steps.
    """
    noise, available = _PoseStream(config, seed).draw(int(n_steps))
    return PoseNoise(noise, available, config.delay_steps)


def imu_noise_series(config: ImuSensorConfig, n_steps: int, seed: int) -> ImuNoise:
    """Draw every random number an IMU uses in an `n_steps` run.

    Args:
        config: The sensor.
        n_steps: Steps N (>= 0), one per sample period.
        seed: Seed of the run; the same seed gives the same arrays.

    Returns:
        White noise (N, 3) and bias (N, 3) on (f_x, f_y, r).
    """
    noise, bias = _ImuStream(config, seed).draw(int(n_steps))
    return ImuNoise(noise, bias)


@njit
def specific_force(nu: FloatArray, nu_dot: FloatArray, out: FloatArray) -> None:
    """Write the noise-free planar IMU reading (f_x, f_y, r) into out (3,).

    Args:
        nu: Body velocities (u, v, r), shape (3,).
        nu_dot: Their time derivatives (m/s^2, m/s^2, rad/s^2), shape (3,).
        out: Output (f_x_mps2, f_y_mps2, r_radps), shape (3,).

    Notes:
        f = nu_dot[0:2] + omega x v = (u_dot - r v, v_dot + r u) for
        omega = (0, 0, r) (Fossen 2021, Ch. 14; planar, IMU at the origin).
    """
    out[0] = nu_dot[0] - nu[2] * nu[1]
    out[1] = nu_dot[1] + nu[2] * nu[0]
    out[2] = nu[2]


@njit
def imu_reading(
    nu: FloatArray, nu_dot: FloatArray, noise_k: FloatArray, bias_k: FloatArray, out: FloatArray
) -> None:
    """Write the IMU reading (f_x, f_y, r) + bias + noise into out (3,).

    Args:
        nu: Body velocities (u, v, r), shape (3,).
        nu_dot: Their derivatives, shape (3,).
        noise_k: Row k of :attr:`ImuNoise.noise`, shape (3,).
        bias_k: Row k of :attr:`ImuNoise.bias`, shape (3,).
        out: Output, shape (3,).
    """
    specific_force(nu, nu_dot, out)
    for i in range(3):
        out[i] += bias_k[i] + noise_k[i]


@njit
def pose_sensor_step(
    ring: FloatArray,
    k: int,
    eta: FloatArray,
    noise_k: FloatArray,
    available_k: bool,
    out: FloatArray,
) -> int:
    """Measure the pose at step k, and deliver the one measured delay steps ago.

    Args:
        ring: Delay line, shape (delay_steps + 1, 4), zeros at the start; row
            k mod (delay + 1) holds (valid, x, y, psi) of step k's measurement.
        k: Step index (>= 0), one per sample period.
        eta: True pose (x_m, y_m, psi_rad) at step k, shape (3,).
        noise_k: Row k of :attr:`PoseNoise.noise`, shape (3,).
        available_k: Row k of :attr:`PoseNoise.available`.
        out: Output (x_m, y_m, psi_rad), shape (3,), written only on delivery.

    Returns:
        The step at which the delivered pose was measured (its time stamp), or
        -1 when nothing is delivered at step k (start-up or dropout).
    """
    n = int(ring.shape[0])
    row = k % n
    ring[row, 0] = 1.0 if available_k else 0.0
    ring[row, 1] = eta[0] + noise_k[0]
    ring[row, 2] = eta[1] + noise_k[1]
    ring[row, 3] = wrap_angle(eta[2] + noise_k[2])
    k_meas = k - (n - 1)
    if k_meas < 0:
        return -1
    src = k_meas % n
    if ring[src, 0] == 0.0:
        return -1
    out[0] = ring[src, 1]
    out[1] = ring[src, 2]
    out[2] = ring[src, 3]
    return k_meas


class SimulatedPoseSensor:
    """Qualisys-like pose sensor: noise, dropouts and latency, one call per period.

    Args:
        config: The sensor.
        seed: Seed; the draws equal :func:`pose_noise_series` with the same seed.
    """

    def __init__(self, config: PoseSensorConfig | None = None, seed: int = 0) -> None:
        self._config = config if config is not None else PoseSensorConfig()
        self._stream = _PoseStream(self._config, seed)
        delay = self._config.delay_steps
        self._ring = np.zeros((delay + 1, 4))
        self._t_ring = np.zeros(delay + 1, dtype=np.int64)
        self._noise = np.empty((0, 3))
        self._available = np.empty(0, dtype=np.bool_)
        self._k = 0
        self._out = np.empty(3)

    @property
    def config(self) -> PoseSensorConfig:
        """Return the configuration."""
        return self._config

    def measure(self, t_ns: int, eta: FloatArray) -> PoseSample | None:
        """Measure the true pose at `t_ns`; return the pose due now, if any.

        Args:
            t_ns: Time of this sample period (ns).
            eta: True pose (x_m, y_m, psi_rad) at `t_ns`, shape (3,), arena frame.

        Returns:
            The pose measured delay_steps periods ago, stamped with its own
            measurement time (with ``stamped_on_receipt``: `t_ns`), or None (start-up
            or dropout).

        Raises:
            StateShapeError: eta is not of shape (3,).
            SampleError: The true pose is not finite.
        """
        i = self._k % _BLOCK
        if i == 0:
            self._noise, self._available = self._stream.draw(_BLOCK)
        self._t_ring[self._k % self._ring.shape[0]] = t_ns
        eta_arr = _vector3("eta", eta)
        k_meas = pose_sensor_step(
            self._ring, self._k, eta_arr, self._noise[i], bool(self._available[i]), self._out
        )
        self._k += 1
        if k_meas < 0:
            return None
        t_meas = int(t_ns) if self._config.stamped_on_receipt \
            else int(self._t_ring[k_meas % self._ring.shape[0]])
        return PoseSample(
            t_meas, float(self._out[0]), float(self._out[1]), float(self._out[2]), Frame.ARENA
        )


class SimulatedImu:
    """BNO055-like planar IMU with noise and bias, one call per period.

    Args:
        config: The sensor.
        seed: Seed; the draws equal :func:`imu_noise_series` with the same seed.
    """

    def __init__(self, config: ImuSensorConfig | None = None, seed: int = 0) -> None:
        self._config = config if config is not None else ImuSensorConfig()
        self._stream = _ImuStream(self._config, seed)
        self._noise = np.empty((0, 3))
        self._bias = np.empty((0, 3))
        self._k = 0
        self._out = np.empty(3)

    @property
    def config(self) -> ImuSensorConfig:
        """Return the configuration."""
        return self._config

    def measure(self, t_ns: int, nu: FloatArray, nu_dot: FloatArray) -> ImuSample:
        """Return the IMU sample at `t_ns` for the true nu (3,) and nu_dot (3,).

        Raises:
            StateShapeError: nu or nu_dot is not of shape (3,).
            SampleError: The reading is not finite (non-finite truth).
        """
        i = self._k % _BLOCK
        if i == 0:
            self._noise, self._bias = self._stream.draw(_BLOCK)
        imu_reading(
            _vector3("nu", nu),
            _vector3("nu_dot", nu_dot),
            self._noise[i],
            self._bias[i],
            self._out,
        )
        self._k += 1
        return ImuSample(int(t_ns), float(self._out[0]), float(self._out[1]), float(self._out[2]))
