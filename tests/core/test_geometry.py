import math

import numpy as np
import pytest

from hil.core.geometry import body_to_world, rotation, wrap_angle, wrap_angles


@pytest.mark.parametrize(
    ("angle", "expected"),
    [
        (0.0, 0.0),
        (math.pi, -math.pi),
        (-math.pi, -math.pi),
        (3 * math.pi, -math.pi),
        (math.pi - 1e-12, math.pi - 1e-12),
        (2 * math.pi + 0.5, 0.5),
        (-2 * math.pi - 0.5, -0.5),
    ],
)
def test_wrap_angle_range_and_value(angle: float, expected: float) -> None:
    got = wrap_angle(angle)
    assert -math.pi <= got < math.pi
    assert got == pytest.approx(expected, abs=1e-12)


def test_wrap_angle_just_below_minus_pi_stays_in_range() -> None:
    got = wrap_angle(float(np.nextafter(-math.pi, -4.0)))
    assert -math.pi <= got < math.pi
    # The input is -pi less one ulp: the same direction as -pi, within rounding.
    assert math.cos(got) == pytest.approx(-1.0)
    assert abs(math.sin(got)) < 1e-12


def test_wrap_angles_matches_scalar_kernel() -> None:
    rng = np.random.default_rng(0)
    angles = rng.uniform(-50, 50, size=1000)
    angles[:4] = [math.pi, -math.pi, 3 * math.pi, -3 * math.pi]
    vector = wrap_angles(angles)
    scalar = np.array([wrap_angle(a) for a in angles])
    np.testing.assert_allclose(vector, scalar, atol=1e-12)
    assert np.all((vector >= -math.pi) & (vector < math.pi))
    np.testing.assert_allclose(np.cos(vector), np.cos(angles), atol=1e-9)
    np.testing.assert_allclose(np.sin(vector), np.sin(angles), atol=1e-9)


def test_rotation_is_orthonormal_and_matches_body_to_world() -> None:
    rng = np.random.default_rng(1)
    for psi in rng.uniform(-math.pi, math.pi, size=20):
        R = rotation(psi)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
        nu = rng.normal(size=3)
        np.testing.assert_allclose(body_to_world(psi, nu), R @ nu, atol=1e-12)


def test_rotation_quarter_turn_maps_surge_to_y() -> None:
    # psi = +90 deg: bow points along world +y, so surge moves the vessel along +y.
    surge = np.array([1.0, 0.0, 0.0])
    np.testing.assert_allclose(body_to_world(math.pi / 2, surge), [0, 1, 0], atol=1e-12)
