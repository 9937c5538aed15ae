import math

import numpy as np
import pytest

from hil.adapters.frames import ArenaTransform, quaternion_from_yaw, yaw_from_quaternion
from hil.core.samples import Frame, PoseSample, SampleError


def test_identity_transform_keeps_the_pose() -> None:
    pose = PoseSample(3, 1.0, -2.0, 0.3, Frame.LAB_NED)
    got = ArenaTransform().to_arena(pose)
    assert (got.x_m, got.y_m, got.frame) == (1.0, -2.0, Frame.ARENA)
    assert got.yaw_rad == pytest.approx(0.3)


def test_known_answer_rotated_and_shifted_arena() -> None:
    # Arena x axis points east (yaw 90 deg from north), origin at north 10, east 5.
    transform = ArenaTransform(origin_north_m=10.0, origin_east_m=5.0, yaw_rad=math.pi / 2)
    # A vessel 2 m east of the origin heading east is at arena x = 2 and heading 0.
    got = transform.to_arena(PoseSample(0, 10.0, 7.0, math.pi / 2, Frame.LAB_NED))
    assert got.x_m == pytest.approx(2.0)
    assert got.y_m == pytest.approx(0.0, abs=1e-12)
    assert got.yaw_rad == pytest.approx(0.0, abs=1e-12)
    # 3 m south of the origin is arena y = +3 (arena y = starboard of x = south here).
    got = transform.to_arena(PoseSample(0, 7.0, 5.0, 0.0, Frame.LAB_NED))
    assert got.x_m == pytest.approx(0.0, abs=1e-12)
    assert got.y_m == pytest.approx(3.0)


def test_body_offset_moves_the_reference_point_with_heading() -> None:
    transform = ArenaTransform(body_offset_x_m=0.2)
    got = transform.to_arena(PoseSample(0, 1.0, 1.0, math.pi / 2, Frame.LAB_NED))
    assert got.x_m == pytest.approx(1.0)
    assert got.y_m == pytest.approx(1.2)


def test_round_trip_random_transforms() -> None:
    rng = np.random.default_rng(4)
    for _ in range(50):
        n0, e0, yaw, dx, dy, body_yaw = (float(v) for v in rng.uniform(-3, 3, size=6))
        transform = ArenaTransform(n0, e0, yaw, dx / 10, dy / 10, body_yaw)
        north, east = rng.uniform(-10, 10, size=2)
        lab = PoseSample(0, float(north), float(east), float(rng.uniform(-3, 3)), Frame.LAB_NED)
        back = transform.to_lab(transform.to_arena(lab))
        assert back.x_m == pytest.approx(lab.x_m)
        assert back.y_m == pytest.approx(lab.y_m)
        assert math.cos(back.yaw_rad - lab.yaw_rad) == pytest.approx(1.0)


def test_quaternion_yaw_round_trip_and_bad_quaternion() -> None:
    for yaw in np.linspace(-3.1, 3.1, 13):
        assert yaw_from_quaternion(*quaternion_from_yaw(float(yaw))) == pytest.approx(yaw)
    with pytest.raises(SampleError, match="unit quaternion"):
        yaw_from_quaternion(0.0, 0.0, 0.0, 0.0)
    with pytest.raises(SampleError, match="unit quaternion"):
        yaw_from_quaternion(math.nan, 0.0, 0.0, 1.0)
