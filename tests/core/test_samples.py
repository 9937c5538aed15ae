import math

import numpy as np
import pytest

from hil.core.samples import (
    Frame,
    ImuSample,
    PoseSample,
    Rectangle,
    SampleError,
    ThrusterCommand,
    VelocityReference,
)


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


def test_rectangle_extent_and_shift() -> None:
    with pytest.raises(SampleError, match="empty extent"):
        Rectangle(1.0, 1.0, 0.0, 1.0)
    moved = Rectangle(0.0, 1.0, 0.0, 2.0).shifted(0.5, -1.0)
    assert moved == Rectangle(0.5, 1.5, -1.0, 1.0)
