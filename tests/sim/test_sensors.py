"""Tests of the simulated pose sensor and IMU: reproducible, right statistics, right timing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.core.samples import Frame, SampleError
from hil.model.errors import StateShapeError
from hil.sim.sensors import (
    ImuSensorConfig,
    PoseSensorConfig,
    SensorConfigError,
    SimulatedImu,
    SimulatedPoseSensor,
    imu_noise_series,
    imu_reading,
    pose_noise_series,
    pose_sensor_step,
    specific_force,
)

DT_NS = 10_000_000


def truth_path(n: int) -> np.ndarray:
    """A heading that crosses +-pi, positions on a slow curve: (n, 3)."""
    t = np.arange(n) * 0.01
    return np.column_stack([np.sin(0.1 * t), 0.2 * t, np.remainder(3.0 + 0.5 * t, 2 * np.pi)])


def twin_specific_force(nu: np.ndarray, nu_dot: np.ndarray) -> np.ndarray:
    omega = np.array([0.0, 0.0, nu[2]])
    vel = np.array([nu[0], nu[1], 0.0])
    f = np.r_[nu_dot[:2], 0.0] + np.cross(omega, vel)
    return np.array([f[0], f[1], nu[2]])


def test_specific_force_and_imu_reading_match_numpy_twin() -> None:
    rng = np.random.default_rng(0)
    out = np.empty(3)
    for _ in range(10):
        nu, nu_dot, noise, bias = rng.normal(size=(4, 3))
        specific_force(nu, nu_dot, out)
        np.testing.assert_allclose(out, twin_specific_force(nu, nu_dot), rtol=1e-15)
        imu_reading(nu, nu_dot, noise, bias, out)
        np.testing.assert_allclose(out, twin_specific_force(nu, nu_dot) + noise + bias, rtol=1e-14)


def test_series_are_reproducible_per_seed() -> None:
    pc = PoseSensorConfig(dropout_rate_hz=0.5)
    ic = ImuSensorConfig()
    a, b, c = (pose_noise_series(pc, 3000, s) for s in (4, 4, 5))
    np.testing.assert_array_equal(a.noise, b.noise)
    np.testing.assert_array_equal(a.available, b.available)
    assert not np.array_equal(a.noise, c.noise)
    i1, i2, i3 = (imu_noise_series(ic, 3000, s) for s in (4, 4, 5))
    np.testing.assert_array_equal(i1.noise, i2.noise)
    np.testing.assert_array_equal(i1.bias, i2.bias)
    assert not np.array_equal(i1.bias, i3.bias)


def test_empty_series_have_no_rows() -> None:
    imu = imu_noise_series(ImuSensorConfig(), 0, 1)
    pose = pose_noise_series(PoseSensorConfig(), 0, 1)
    assert imu.noise.shape == imu.bias.shape == pose.noise.shape == (0, 3)
    assert pose.available.shape == (0,)


def test_pose_noise_statistics() -> None:
    pc = PoseSensorConfig(noise_std_x_m=0.001, noise_std_y_m=0.003, noise_std_yaw_rad=0.002)
    series = pose_noise_series(pc, 40_000, 1)
    std = series.noise.std(axis=0)
    np.testing.assert_allclose(std, [0.001, 0.003, 0.002], rtol=0.03)
    np.testing.assert_allclose(series.noise.mean(axis=0), 0.0, atol=3e-5)
    assert series.available.all()


def test_imu_noise_and_bias_statistics() -> None:
    ic = ImuSensorConfig(
        accel_noise_std_mps2=0.02,
        gyro_noise_std_radps=0.002,
        accel_bias_mps2=(0.05, -0.04),
        gyro_bias_radps=0.01,
        accel_bias_walk_mps2_per_sqrt_s=0.003,
        gyro_bias_walk_radps_per_sqrt_s=0.0005,
    )
    series = imu_noise_series(ic, 40_000, 2)
    np.testing.assert_allclose(series.noise.std(axis=0), [0.02, 0.02, 0.002], rtol=0.03)
    np.testing.assert_array_equal(series.bias[0], [0.05, -0.04, 0.01])
    steps = np.diff(series.bias, axis=0)
    want = np.array([0.003, 0.003, 0.0005]) * math.sqrt(0.01)
    np.testing.assert_allclose(steps.std(axis=0), want, rtol=0.03)
    still = imu_noise_series(
        ImuSensorConfig(accel_bias_walk_mps2_per_sqrt_s=0.0, gyro_bias_walk_radps_per_sqrt_s=0.0),
        100,
        2,
    )
    np.testing.assert_array_equal(still.bias, np.tile([0.03, -0.02, 0.003], (100, 1)))


def test_random_dropouts_have_the_configured_rate_and_length() -> None:
    pc = PoseSensorConfig(dropout_rate_hz=0.2, dropout_duration_s=1.0)
    available = pose_noise_series(pc, 400_000, 3).available
    lost = 1.0 - available.mean()
    assert lost == pytest.approx(pc.expected_dropout_fraction(), rel=0.15)
    # Every run of lost samples is a whole number of 1-s outages (but a cut-off last one).
    edges = np.flatnonzero(np.diff(np.r_[1, available.astype(np.int8), 1]))
    runs = edges[1::2] - edges[0::2]
    if not available[-1]:
        runs = runs[:-1]
    assert runs.size > 100
    assert np.all(runs % 100 == 0)


def test_scheduled_dropout_loses_exactly_its_window() -> None:
    pc = PoseSensorConfig(scheduled_dropouts_s=((2.0, 1.0),))
    available = pose_noise_series(pc, 500, 0).available
    assert not available[200:300].any()
    assert available[:200].all()
    assert available[300:].all()


def test_pose_sensor_delivers_late_with_the_measurement_stamp() -> None:
    pc = PoseSensorConfig(latency_s=0.03, scheduled_dropouts_s=((1.0, 0.5),))
    n = 2600  # crosses the sensor's draw blocks
    eta = truth_path(n)
    series = pose_noise_series(pc, n, 11)
    sensor = SimulatedPoseSensor(pc, seed=11)
    delivered = 0
    for i in range(n):
        sample = sensor.measure(i * DT_NS, eta[i])
        j = i - 3
        if j < 0 or not series.available[j]:
            assert sample is None
            continue
        assert sample is not None
        delivered += 1
        assert sample.t_ns == j * DT_NS
        assert sample.frame is Frame.ARENA
        want = eta[j] + series.noise[j]
        assert (sample.x_m, sample.y_m) == (want[0], want[1])
        assert sample.yaw_rad == pytest.approx(math.remainder(want[2], 2 * math.pi), abs=1e-12)
        assert -math.pi <= sample.yaw_rad < math.pi
    assert delivered == n - 3 - 50


def test_pose_sensor_step_kernel_with_no_latency_delivers_at_once() -> None:
    ring = np.zeros((1, 4))
    out = np.zeros(3)
    eta = np.array([1.0, 2.0, math.pi - 1e-3])
    noise = np.array([0.0, 0.0, 2e-3])
    assert pose_sensor_step(ring, 0, eta, noise, True, out) == 0
    np.testing.assert_allclose(out, [1.0, 2.0, -math.pi + 1e-3], atol=1e-12)
    assert pose_sensor_step(ring, 1, eta, noise, False, out) == -1


def test_simulated_imu_uses_the_series_draws() -> None:
    ic = ImuSensorConfig()
    n = 2100
    series = imu_noise_series(ic, n, 21)
    imu = SimulatedImu(ic, seed=21)
    rng = np.random.default_rng(0)
    for i in range(n):
        nu, nu_dot = rng.normal(size=(2, 3)) * 0.1
        sample = imu.measure(i * DT_NS, nu, nu_dot)
        want = twin_specific_force(nu, nu_dot) + series.noise[i] + series.bias[i]
        assert sample.t_ns == i * DT_NS
        np.testing.assert_allclose(sample.as_array(), want, rtol=1e-14, atol=1e-17)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"rate_hz": 0.0}, "rate_hz"),
        ({"noise_std_x_m": -0.001}, "noise_std_x_m"),
        ({"latency_s": math.nan}, "latency_s"),
        ({"dropout_rate_hz": 100.0}, "dropout_rate_hz"),
        ({"scheduled_dropouts_s": ((1.0, -1.0),)}, "duration"),
        ({"scheduled_dropouts_s": ((1.0,),)}, "start_s, duration_s"),
    ],
)
def test_invalid_pose_config_is_refused(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(SensorConfigError, match=match):
        PoseSensorConfig(**kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"gyro_noise_std_radps": -1.0}, "gyro_noise_std_radps"),
        ({"accel_bias_mps2": (0.0, math.inf)}, "biases"),
        ({"gyro_bias_walk_radps_per_sqrt_s": -1e-3}, "gyro_bias_walk"),
    ],
)
def test_invalid_imu_config_is_refused(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(SensorConfigError, match=match):
        ImuSensorConfig(**kwargs)  # type: ignore[arg-type]


def test_runtime_sensors_refuse_bad_truth() -> None:
    with pytest.raises(StateShapeError, match="eta"):
        SimulatedPoseSensor(PoseSensorConfig(latency_s=0.0)).measure(0, np.zeros(2))
    with pytest.raises(SampleError, match="non-finite"):
        SimulatedPoseSensor(PoseSensorConfig(latency_s=0.0)).measure(0, np.array([0, np.nan, 0]))
    with pytest.raises(StateShapeError, match="nu_dot"):
        SimulatedImu().measure(0, np.zeros(3), np.zeros(4))
