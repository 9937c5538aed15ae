"""The thrust envelope: the largest force (X, Y, N) the thrusters can make.

The achievable set is the tunnel segment plus two discs (an azimuth can point its
thrust anywhere), mapped through ``B_e`` (:mod:`hil.controllers.allocation_kernels`).
"""

from __future__ import annotations

import math

import numpy as np

from hil.controllers.allocation_kernels import extended_matrix, force_limits
from hil.core.arrays import FloatArray
from hil.model.thrusters import VOYAGER_THRUSTERS, ThrusterParams

__all__ = ["axis_force_limits", "support_force"]


def support_force(params: ThrusterParams, direction: FloatArray) -> float:
    """Return max over achievable tau of ``direction . tau`` (the envelope's support).

    The achievable set is the tunnel segment plus two discs (any azimuth angle), so
    the maximum is a sum of per-thruster terms.
    """
    tp = params.as_array()
    be = extended_matrix(tp)
    w = np.asarray(direction, dtype=np.float64) @ be
    fmax = force_limits(tp)
    return float(
        abs(w[0]) * fmax[0] + math.hypot(w[1], w[2]) * fmax[1] + math.hypot(w[3], w[4]) * fmax[2]
    )


def axis_force_limits(params: ThrusterParams = VOYAGER_THRUSTERS) -> FloatArray:
    """Return the largest |X|, |Y|, |N| achievable alone on each axis, shape (3,)."""
    return np.array([support_force(params, e) for e in np.eye(3)])
