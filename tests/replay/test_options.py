"""Replay thresholds parsed from ``--tolerance``."""

from __future__ import annotations

import numpy as np
import pytest

from hil.replay.options import Tolerance


def test_tolerance_parsing() -> None:
    tol = Tolerance.parse("surge=0.05, yaw=4,rel=0.1")
    assert tol.rms[0] == 0.05
    assert tol.rms[2] == 4.0
    assert tol.enforce_rms
    assert tol.rms[1] == np.inf  # only the axes given are enforced
    assert tol.relative == 0.1
    assert not Tolerance.parse("").enforce_rms
    assert Tolerance.parse("sway_max=0.3").max_abs == (np.inf, 0.3, np.inf)
    with pytest.raises(ValueError, match="unknown tolerance key 'heave'"):
        Tolerance.parse("heave=1")
    with pytest.raises(ValueError, match="'surge=-1'"):
        Tolerance.parse("surge=-1")
    with pytest.raises(ValueError, match="'yaw'"):
        Tolerance.parse("yaw")
