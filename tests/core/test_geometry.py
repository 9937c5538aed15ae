import math

import numpy as np
import pytest

from hil.core.geometry import (
    body_to_world,
    quaternion_yaw,
    quaternion_yaws,
    rotation,
    wrap_angle,
    wrap_angles,
    yaw_quaternion,
    yaw_quaternions,
)


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


def _hamilton(a: tuple[float, ...], b: tuple[float, ...]) -> tuple[float, ...]:
    """Return the product a b of quaternions in ROS order (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def test_yaw_and_quaternion_are_one_convention_scalar_and_vectorized() -> None:
    rng = np.random.default_rng(4)
    yaws = rng.uniform(-math.pi, math.pi, 200)
    quats = yaw_quaternions(yaws)
    assert quats.shape == (200, 4)
    for yaw, q in zip(yaws, quats, strict=True):
        assert yaw_quaternion(float(yaw)) == pytest.approx(tuple(q), abs=1e-15)
        assert quaternion_yaw(*q) == pytest.approx(yaw, abs=1e-12)
        # A roll and pitch after the yaw (the mocap's small tilts) keep the yaw:
        # q = q_yaw * q_pitch * q_roll (z-y-x), so its z-y-x yaw is the same.
        tilt = _hamilton(
            (0.0, math.sin(0.02), 0.0, math.cos(0.02)), (math.sin(-0.03), 0.0, 0.0, math.cos(0.03))
        )
        assert quaternion_yaw(*_hamilton(tuple(q), tilt)) == pytest.approx(yaw, abs=1e-12)
    np.testing.assert_allclose(quaternion_yaws(*quats.T), yaws, atol=1e-12)
    # A half turn stays a half turn, wrapped to [-pi, pi) in both forms. Whether it reads
    # as -pi or as pi less an ulp depends on the libm's atan2 rounding (cos(pi/2) is 6e-17,
    # not 0), so only the wrap and the angle are asserted, to 1e-12 rad.
    for half_turn in (
        quaternion_yaw(*yaw_quaternion(math.pi)),
        float(quaternion_yaws(*yaw_quaternions(np.array([math.pi])).T)[0]),
    ):
        assert -math.pi <= half_turn < math.pi
        assert abs(abs(half_turn) - math.pi) < 1e-12
