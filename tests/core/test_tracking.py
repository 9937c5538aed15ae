"""The one tracking error: join (zero-order hold), units (SI) and sign (nu - nu_ref)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.core.tracking import DISPLAY_UNITS, for_display, tracking_error

MS = 1_000_000


def test_a_closed_form_ramp_against_held_references() -> None:
    """u(t) = a t against steps held at 0.2 then 0.5 m/s: e = a t - held, RMS in closed form."""
    a = 0.1  # m/s per s
    t_ns = np.arange(0, 4000 * MS, 500 * MS, dtype=np.int64)  # 0, 0.5, ..., 3.5 s
    t_s = t_ns / 1e9
    nu = np.column_stack([a * t_s, -0.5 * a * t_s, np.full(len(t_s), 0.02)])
    ref_t = np.array([1000 * MS, 2200 * MS], dtype=np.int64)  # the second between samples
    nu_ref = np.array([[0.2, 0.0, 0.0], [0.5, 0.1, 0.01]])
    series = tracking_error(t_ns, nu, ref_t, nu_ref)
    # Samples before the first reference (0 and 0.5 s) are left out.
    assert series.t_ns.tolist() == t_ns[2:].tolist()
    kept = t_s[2:]
    held = np.where(kept < 2.2, 0, 1)
    expected = nu[2:] - nu_ref[held]
    np.testing.assert_allclose(series.error, expected)
    # Sign: faster than commanded is positive.
    assert series.error[0, 0] == pytest.approx(0.1 * 1.0 - 0.2)
    surge = a * kept - np.where(kept < 2.2, 0.2, 0.5)
    assert series.rms()[0] == pytest.approx(math.sqrt(np.mean(surge**2)))
    peak, when = series.peak()
    assert peak[0] == pytest.approx(np.abs(surge).max())
    assert when[0] == round(kept[np.argmax(np.abs(surge))] * 1e9)
    # Yaw stays in rad/s: 0.02 - 0.01 after the second reference.
    assert series.error[-1, 2] == pytest.approx(0.01)


def test_a_reference_at_the_sample_time_is_in_force_at_it() -> None:
    t = np.array([0, 10 * MS], dtype=np.int64)
    series = tracking_error(t, np.ones((2, 3)), t, np.array([[1.0, 1, 1], [0.0, 0, 0]]))
    np.testing.assert_array_equal(series.error, [[0, 0, 0], [1, 1, 1]])


def test_no_reference_means_no_error_samples() -> None:
    t = np.array([0, 10 * MS], dtype=np.int64)
    series = tracking_error(t, np.ones((2, 3)), np.zeros(0, np.int64), np.zeros((0, 3)))
    assert len(series) == 0
    assert np.isnan(series.rms()).all()
    assert np.isnan(series.peak()[0]).all()


def test_bad_inputs_are_refused() -> None:
    t = np.array([0, 10 * MS], dtype=np.int64)
    with pytest.raises(ValueError, match="differ in length"):
        tracking_error(t, np.ones((3, 3)), t, np.ones((2, 3)))
    with pytest.raises(ValueError, match="ascending"):
        tracking_error(t, np.ones((2, 3)), t[::-1].copy(), np.ones((2, 3)))


def test_display_turns_only_the_yaw_into_degrees() -> None:
    shown = for_display(np.array([[0.1, 0.2, math.pi]]))
    np.testing.assert_allclose(shown, [[0.1, 0.2, 180.0]])
    assert for_display(np.array([0.0, 0.0, math.pi / 2]))[2] == pytest.approx(90.0)
    assert DISPLAY_UNITS[2] == "deg/s"
