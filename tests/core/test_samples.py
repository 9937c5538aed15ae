import math

import numpy as np
import pytest

from hil.core.samples import (
    Frame,
    ImuSample,
    ObstacleLayout,
    PoseSample,
    SampleError,
    ThrusterCommand,
    VelocityReference,
    obstacle_rect,
)
from hil.core.shapes import Rect


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_samples_are_refused(bad: float) -> None:
    with pytest.raises(SampleError, match="non-finite"):
        PoseSample(0, bad, 0.0, 0.0)
    with pytest.raises(SampleError, match="non-finite"):
        ImuSample(0, 0.0, bad, 0.0)
    with pytest.raises(SampleError, match="non-finite"):
        VelocityReference(0, 0.0, 0.0, bad)
    with pytest.raises(SampleError, match="non-finite"):
        ThrusterCommand(0, 0.0, 0.0, 0.0, bad, 0.0)


def test_pose_frame_is_part_of_the_value() -> None:
    pose = PoseSample(1, 1.0, 2.0, 0.5, Frame.LAB_NED)
    with pytest.raises(SampleError, match="world_ned"):
        pose.eta(Frame.ARENA)
    np.testing.assert_array_equal(pose.eta(Frame.LAB_NED), [1.0, 2.0, 0.5])


def test_thruster_command_outside_unit_range_is_refused() -> None:
    with pytest.raises(SampleError, match=r"outside \[-1, 1\]"):
        ThrusterCommand(0, 0.0, 1.5, 0.0, 0.0, 0.0)
    stop = ThrusterCommand.zero(7)
    assert (stop.tunnel, stop.port, stop.starboard) == (0.0, 0.0, 0.0)
    assert stop.t_ns == 7


@pytest.mark.parametrize(
    ("rect", "match"),
    [(Rect(1.0, 1.0, 0.0, 1.0), "empty extent"), (Rect(0.0, math.nan, 0.0, 1.0), "non-finite")],
)
def test_layout_refuses_empty_or_non_finite_obstacles(rect: Rect, match: str) -> None:
    with pytest.raises(SampleError, match=match):
        ObstacleLayout(0, (Rect(0.0, 1.0, 0.0, 1.0), rect))
    with pytest.raises(SampleError, match=match):
        obstacle_rect(rect.x_min_m, rect.x_max_m, rect.y_min_m, rect.y_max_m)


def test_obstacle_rect_is_the_shape_rect() -> None:
    rect = obstacle_rect(0.0, 1.0, 0.0, 2.0)
    assert rect == Rect(0.0, 1.0, 0.0, 2.0)
    assert ObstacleLayout(0, (rect.translate(0.5, -1.0),)).obstacles == (Rect(0.5, 1.5, -1.0, 1.0),)
