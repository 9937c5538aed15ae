"""The simulated pose sensor gives each named pose feed: rate, delay and stamping."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from hil.core.pose_feeds import DEFAULT_POSE_FEED, POSE_FEEDS, pose_feed
from hil.sim.closed_loop import LowLevelConfig, simulate_closed_loop
from hil.sim.errors import ClosedLoopConfigError
from hil.sim.sensors import PoseSensorConfig, SimulatedPoseSensor, pose_sensor_for

NS = 1_000_000_000


def test_every_feed_maps_to_its_sensor() -> None:
    qtm = pose_sensor_for(pose_feed(DEFAULT_POSE_FEED))
    assert qtm == PoseSensorConfig()  # the sensor the shipped [transient] was measured with
    ros = pose_sensor_for(pose_feed("ros-10hz-receive-stamped"))
    assert ros.rate_hz == 10.0
    assert ros.stamped_on_receipt
    assert ros.latency_s == POSE_FEEDS["ros-10hz-receive-stamped"].delay_s


def test_unknown_feed_names_the_known_ones() -> None:
    with pytest.raises(KeyError, match="qtm-100hz"):
        pose_feed("ros-1hz")


@pytest.mark.parametrize("on_receipt", [False, True])
def test_runtime_sensor_stamps_at_capture_or_on_receipt(on_receipt: bool) -> None:
    config = PoseSensorConfig(rate_hz=10.0, latency_s=0.1, noise_std_x_m=0.0,
                              noise_std_y_m=0.0, noise_std_yaw_rad=0.0,
                              stamped_on_receipt=on_receipt)
    sensor = SimulatedPoseSensor(config)
    samples = []
    for k in range(5):  # the truth moves 1 m per period in x
        sample = sensor.measure(k * NS // 10, np.array([float(k), 0.0, 0.0]))
        if sample is not None:
            samples.append((k, sample))
    assert [k for k, _ in samples] == [1, 2, 3, 4]  # delivered one period late
    for k, sample in samples:
        assert sample.x_m == pytest.approx(k - 1.0)  # measured one period before delivery
        assert sample.t_ns == (k if on_receipt else k - 1) * NS // 10


def test_closed_loop_refuses_a_rate_that_does_not_divide_the_physics_rate() -> None:
    with pytest.raises(ClosedLoopConfigError, match="must divide"):
        LowLevelConfig(pose_sensor=PoseSensorConfig(rate_hz=30.0))


def _estimate_error(sensor: PoseSensorConfig) -> float:
    refs = np.array([[0.2, 0.0, 0.0], [0.2, 0.1, 0.2], [0.0, 0.0, 0.0]])
    res = simulate_closed_loop(refs, LowLevelConfig(pose_sensor=sensor, seed=3))
    late = res.t_s >= 1.0
    return float(np.max(np.hypot(*(res.eta_hat[late, :2] - res.eta[late, :2]).T)))


def test_a_hidden_delay_costs_the_estimate_what_capture_stamps_save() -> None:
    capture = PoseSensorConfig(rate_hz=10.0, latency_s=0.02)
    receipt = replace(capture, stamped_on_receipt=True)
    exact = _estimate_error(capture)
    hidden = _estimate_error(receipt)
    # 0.2 m/s x 20 ms = 4 mm of lag the filter cannot see, beside its own error.
    assert hidden > exact + 0.002, (exact, hidden)
    assert _estimate_error(PoseSensorConfig()) < exact  # 100 Hz beats 10 Hz
