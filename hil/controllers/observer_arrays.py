"""The EKF's state as arrays: the bundle the event kernels share, its counters and codes.

:class:`EkfArrays` holds the posterior, the ring buffer of past priors (see
:mod:`hil.controllers.observer_ring`) and the counters; ``C_*`` index the counters,
``S_*`` are the status codes the event kernels in
:mod:`hil.controllers.observer_kernels` return. The state and parameter layouts
(``I_*``, ``P_*``) are in :mod:`hil.controllers.observer_math`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from hil.controllers.observer_math import N_STATE
from hil.core.arrays import FloatArray, IntArray

__all__ = [
    "C_GYRO_GATED",
    "C_IMU_ABSURD",
    "C_IMU_DUPLICATE",
    "C_IMU_FUSED",
    "C_IMU_LATE",
    "C_IMU_NONFINITE",
    "C_IMU_TOO_OLD",
    "C_NOT_INITIALIZED",
    "C_POSE_ABSURD",
    "C_POSE_DUPLICATE",
    "C_POSE_FUSED",
    "C_POSE_GATED",
    "C_POSE_LATE",
    "C_POSE_NONFINITE",
    "C_POSE_RESET",
    "C_POSE_TOO_OLD",
    "NOT_REFUSED",
    "N_COUNTERS",
    "S_ABSURD",
    "S_DUPLICATE",
    "S_FUSED",
    "S_GATED",
    "S_NONFINITE",
    "S_NOT_INITIALIZED",
    "S_RESET",
    "S_TOO_OLD",
    "EkfArrays",
    "allocate_arrays",
]

# Counter indices (counters array, int64).
C_POSE_FUSED = 0
C_POSE_LATE = 1  # fused although stamped before the filter time
C_POSE_NONFINITE = 2
C_POSE_ABSURD = 3
C_POSE_GATED = 4
C_POSE_TOO_OLD = 5
C_POSE_DUPLICATE = 6
C_IMU_FUSED = 7
C_IMU_LATE = 8
C_IMU_NONFINITE = 9
C_IMU_ABSURD = 10
C_GYRO_GATED = 11
C_IMU_TOO_OLD = 12
C_IMU_DUPLICATE = 13
C_NOT_INITIALIZED = 14
C_POSE_RESET = 15  # filter restarted after P_GATE_RESET gated poses in a row
N_COUNTERS = 16

# Status codes returned by the event kernels.
S_FUSED = 0
S_NONFINITE = 1
S_ABSURD = 2
S_GATED = 3
S_TOO_OLD = 4
S_DUPLICATE = 5
S_NOT_INITIALIZED = 6
S_RESET = 7  # the pose restarted the filter (see _gated)
NOT_REFUSED = -1
"""What a refusal check returns for a sample it lets through (no ``S_*`` code)."""


class EkfArrays(NamedTuple):
    """Every array the event kernels read or write; numba passes it as a tuple.

    Attributes:
        x: Posterior state at the filter time, shape (9,), ``I_*`` indexing.
        P: Posterior covariance, shape (9, 9).
        hist_t_ns: Time stamp of each ring slot (ns), shape (K,), int64.
        hist_x: Prior state at each slot time (before its measurements), (K, 9).
        hist_cov: Prior covariance at each slot time, (K, 9, 9).
        hist_u: Accelerometer input held from each slot to the next, (K, 3):
            (f_x, f_y) in m/s^2 and an "own sample" flag (1.0 or 0.0).
        hist_z: Measurements stamped at each slot, (K, 4): pose (x, y, psi) and
            yaw rate; NaN where the slot has none.
        meta: Bookkeeping, (4,), int64: oldest slot, slot count, initialized,
            poses gated in a row.
        counters: Sample counters, (N_COUNTERS,), int64, ``C_*`` indexing.
        params: Noise, gates and limits, (N_PARAMS,), ``P_*`` indexing.
        innovation: The last pose's innovation against its prior, (3,): normalized
            innovation squared, |position| (m), |heading| (rad)
            (:func:`~hil.controllers.observer_math.pose_innovation`); NaN when that
            pose was refused before its gate (non-finite, absurd, too old, duplicate).
    """

    x: FloatArray
    P: FloatArray
    hist_t_ns: IntArray
    hist_x: FloatArray
    hist_cov: FloatArray
    hist_u: FloatArray
    hist_z: FloatArray
    meta: IntArray
    counters: IntArray
    params: FloatArray
    innovation: FloatArray


def allocate_arrays(params: FloatArray, history_len: int) -> EkfArrays:
    """Allocate an uninitialized :class:`EkfArrays` with `history_len` ring slots.

    Args:
        params: Parameter vector, shape (N_PARAMS,) (copied).
        history_len: Ring slots K (>= 2); each sample time takes one slot.

    Returns:
        Zeroed arrays; call :func:`obs_init` before feeding samples.
    """
    k = int(history_len)
    return EkfArrays(
        x=np.zeros(N_STATE),
        P=np.zeros((N_STATE, N_STATE)),
        hist_t_ns=np.zeros(k, dtype=np.int64),
        hist_x=np.zeros((k, N_STATE)),
        hist_cov=np.zeros((k, N_STATE, N_STATE)),
        hist_u=np.zeros((k, 3)),
        hist_z=np.full((k, 4), np.nan),
        meta=np.zeros(4, dtype=np.int64),
        counters=np.zeros(N_COUNTERS, dtype=np.int64),
        params=np.array(params, dtype=np.float64, copy=True),
        innovation=np.full(3, np.nan),
    )
