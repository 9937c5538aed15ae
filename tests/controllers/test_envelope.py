"""The thrust envelope against the thruster layout in closed form."""

from __future__ import annotations

import math

import pytest

from hil.controllers.envelope import axis_force_limits


def test_axis_force_limits() -> None:
    lim = axis_force_limits()
    assert lim[0] == pytest.approx(2.06)  # both azimuths ahead
    assert lim[1] == pytest.approx(1.8403 + 2.06)  # tunnel plus both azimuths abeam
    assert lim[2] == pytest.approx(0.3875 * 1.8403 + 2 * math.hypot(0.4574, 0.055) * 1.03)
