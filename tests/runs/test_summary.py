"""The run summary's tracking error: the one of hil.core.tracking, yaw shown in deg/s."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.core.tracking import tracking_error
from hil.runs.summary import TrackingError


def test_tracking_error_is_the_one_join_with_yaw_in_degrees() -> None:
    ticks = np.arange(4, dtype=np.int64) * 50_000_000
    nu = np.array([[0.1, 0.0, 0.01], [0.2, 0.0, 0.01], [0.3, 0.0, -0.01], [0.4, 0.0, 0.03]])
    nu_ref = np.array([[0.1, 0.0, 0.0]] * 4)
    summary = TrackingError.of(tracking_error(ticks, nu, ticks, nu_ref))
    assert summary.samples == 4
    surge = np.array([0.0, 0.1, 0.2, 0.3])
    assert summary.rms[0] == pytest.approx(math.sqrt(np.mean(surge**2)))
    assert summary.max_abs[0] == pytest.approx(0.3)
    assert summary.rms[2] == pytest.approx(math.degrees(math.sqrt((3 * 0.01**2 + 0.03**2) / 4)))
    assert summary.max_abs[2] == pytest.approx(math.degrees(0.03))


def test_no_ticks_under_control_gives_nan() -> None:
    empty = np.zeros(0, dtype=np.int64)
    summary = TrackingError.of(tracking_error(empty, np.zeros((0, 3)), empty, np.zeros((0, 3))))
    assert summary.samples == 0
    assert all(math.isnan(v) for v in (*summary.rms, *summary.max_abs))
