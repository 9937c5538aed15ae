"""The EKF adapter: a known start velocity is taken at the first pose, once."""

from __future__ import annotations

import numpy as np

from hil.core.samples import PoseSample
from hil.runtime.assembly import EkfObserver


def test_the_filter_starts_from_a_given_velocity_at_its_first_pose() -> None:
    observer = EkfObserver(start_nu=np.array([0.1, -0.05, 0.2]))
    assert observer.estimate() is None
    assert observer.update_pose(PoseSample(0, 1.0, 2.0, 0.3))
    estimate = observer.estimate()
    assert estimate is not None
    eta, nu = estimate
    np.testing.assert_allclose(eta, (1.0, 2.0, 0.3))
    np.testing.assert_allclose(nu, (0.1, -0.05, 0.2))
    assert observer.ekf.counters().pose_fused == 1


def test_without_a_start_velocity_the_filter_starts_at_rest() -> None:
    observer = EkfObserver()
    assert observer.update_pose(PoseSample(0, 1.0, 2.0, 0.3))
    estimate = observer.estimate()
    assert estimate is not None
    np.testing.assert_array_equal(estimate[1], np.zeros(3))
