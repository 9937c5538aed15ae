"""Ring buffer of past EKF priors: the bookkeeping behind late and out-of-order samples.

Each slot holds one sample time: the prior (state and covariance) at that time
before its measurements, the accelerometer input held from it to the next slot,
and the measurements stamped there. Slots are kept in time order in a ring of
K; a late sample opens (or joins) the slot of its stamp and the filter is re-run
forward from there with :func:`rerun`. The arrays, passed one by one (passing
the whole :class:`~hil.controllers.observer_arrays.EkfArrays` tuple to every
helper costs ~70 ns a call):

* ``ht`` (K,) int64 stamps (ns); ``hx`` (K, 9) priors; ``hc`` (K, 9, 9) their
  covariances; ``hu`` (K, 3) held inputs (``U_*`` columns); ``hz`` (K, 4)
  measurements (``Z_*`` columns, NaN = none); ``meta`` (4,) int64 (``M_*``).

Logical slot 0 is the oldest, ``meta[M_COUNT] - 1`` the newest (the filter time).
"""

from __future__ import annotations

import math

import numpy as np

from hil.controllers.observer_math import (
    N_STATE,
    P_MAX_DELAY,
    P_R_GYRO,
    P_R_PSI,
    P_R_X,
    P_R_Y,
    _update_pose,
    ekf_predict,
    ekf_update_yaw_rate,
)
from hil.core.arrays import FloatArray, IntArray
from hil.core.jit import njit

# meta array (int64, shape (4,)).
M_START = 0  # physical index of the oldest slot
M_COUNT = 1  # slots in use
M_INIT = 2  # 1 once obs_init ran
M_GATED_RUN = 3  # poses gated in a row

# History input columns (hist_u, shape (K, 3)).
U_AX = 0
U_AY = 1
U_OWN = 2  # 1.0 when an IMU sample stamped at this slot set the input

# History measurement columns (hist_z, shape (K, 4)); NaN means "none".
Z_X = 0
Z_Y = 1
Z_PSI = 2
Z_R = 3

NS_TO_S = 1e-9


@njit
def slot_index(meta: IntArray, k_len: int, logical: int) -> int:
    """Return the physical ring index of logical slot `logical` (0 = oldest)."""
    return int((meta[M_START] + logical) % k_len)


@njit
def head_time(ht: IntArray, meta: IntArray) -> int:
    """Return the stamp of the newest slot (the filter time)."""
    return int(ht[slot_index(meta, ht.shape[0], meta[M_COUNT] - 1)])


@njit
def find_slot(ht: IntArray, meta: IntArray, t_ns: int) -> int:
    """Return the newest logical slot stamped at or before `t_ns`, or -1."""
    k_len = ht.shape[0]
    for logical in range(meta[M_COUNT] - 1, -1, -1):
        if ht[slot_index(meta, k_len, logical)] <= t_ns:
            return logical
    return -1


@njit
def fuse_stored(x: FloatArray, P: FloatArray, hz: FloatArray, p: int, prm: FloatArray) -> None:
    """Re-fuse slot p's stored measurements (accepted once already: no gate)."""
    if not math.isnan(hz[p, Z_X]):
        _update_pose(
            x,
            P,
            hz[p, Z_X],
            hz[p, Z_Y],
            hz[p, Z_PSI],
            prm[P_R_X],
            prm[P_R_Y],
            prm[P_R_PSI],
            math.inf,
        )
    if not math.isnan(hz[p, Z_R]):
        ekf_update_yaw_rate(x, P, hz[p, Z_R], prm[P_R_GYRO], math.inf)


@njit
def store_prior(hx: FloatArray, hc: FloatArray, p: int, x: FloatArray, P: FloatArray) -> None:
    """Copy (x, P) into slot p's prior."""
    for i in range(N_STATE):
        hx[p, i] = x[i]
        for j in range(N_STATE):
            hc[p, i, j] = P[i, j]


@njit
def load_prior(hx: FloatArray, hc: FloatArray, p: int, x: FloatArray, P: FloatArray) -> None:
    """Copy slot p's prior into (x, P)."""
    for i in range(N_STATE):
        x[i] = hx[p, i]
        for j in range(N_STATE):
            P[i, j] = hc[p, i, j]


@njit
def prior_at(
    x: FloatArray,
    P: FloatArray,
    ht: IntArray,
    hx: FloatArray,
    hc: FloatArray,
    hu: FloatArray,
    hz: FloatArray,
    meta: IntArray,
    prm: FloatArray,
    j: int,
    t_ns: int,
    xs: FloatArray,
    Ps: FloatArray,
) -> None:
    """Fill xs, Ps with the state at `t_ns` >= t_j from slot j, before new data at t_ns."""
    k_len = ht.shape[0]
    pj = slot_index(meta, k_len, j)
    if j == meta[M_COUNT] - 1:
        xs[:] = x
        Ps[:, :] = P
    else:
        load_prior(hx, hc, pj, xs, Ps)
        fuse_stored(xs, Ps, hz, pj, prm)
    if t_ns > ht[pj]:
        ekf_predict(xs, Ps, (t_ns - ht[pj]) * NS_TO_S, hu[pj, U_AX], hu[pj, U_AY], prm)


@njit
def make_room(meta: IntArray, k_len: int, j: int) -> int:
    """Drop the oldest slot if the ring is full; return slot j's new logical index."""
    if meta[M_COUNT] == k_len:
        meta[M_START] = (meta[M_START] + 1) % k_len
        meta[M_COUNT] -= 1
        return j - 1
    return j


@njit
def insert_slot(
    ht: IntArray,
    hx: FloatArray,
    hc: FloatArray,
    hu: FloatArray,
    hz: FloatArray,
    meta: IntArray,
    q: int,
    t_ns: int,
) -> int:
    """Open logical slot q >= 1 at `t_ns` (ring not full), shifting newer slots; return it."""
    k_len = ht.shape[0]
    count = meta[M_COUNT]
    for logical in range(count, q, -1):
        dst = slot_index(meta, k_len, logical)
        src = slot_index(meta, k_len, logical - 1)
        ht[dst] = ht[src]
        hx[dst] = hx[src]
        hc[dst] = hc[src]
        hu[dst] = hu[src]
        hz[dst] = hz[src]
    meta[M_COUNT] = count + 1
    p = slot_index(meta, k_len, q)
    prev = slot_index(meta, k_len, q - 1)
    ht[p] = t_ns
    for col in range(4):
        hz[p, col] = np.nan
    # Zero-order hold: the input of the slot before goes on until the next IMU sample.
    hu[p, U_AX] = hu[prev, U_AX]
    hu[p, U_AY] = hu[prev, U_AY]
    hu[p, U_OWN] = 0.0
    return p


@njit
def rerun(
    x: FloatArray,
    P: FloatArray,
    ht: IntArray,
    hx: FloatArray,
    hc: FloatArray,
    hu: FloatArray,
    hz: FloatArray,
    meta: IntArray,
    prm: FloatArray,
    l0: int,
) -> None:
    """Re-filter from logical slot l0's stored prior up to the newest slot."""
    p = slot_index(meta, ht.shape[0], l0)
    load_prior(hx, hc, p, x, P)
    fuse_stored(x, P, hz, p, prm)
    propagate(x, P, ht, hx, hc, hu, hz, meta, prm, l0)


@njit
def propagate(
    x: FloatArray,
    P: FloatArray,
    ht: IntArray,
    hx: FloatArray,
    hc: FloatArray,
    hu: FloatArray,
    hz: FloatArray,
    meta: IntArray,
    prm: FloatArray,
    l0: int,
) -> None:
    """Carry (x, P), the posterior at logical slot l0, forward to the newest slot."""
    k_len = ht.shape[0]
    p = slot_index(meta, k_len, l0)
    for logical in range(l0 + 1, meta[M_COUNT]):
        q = p
        p = slot_index(meta, k_len, logical)
        ekf_predict(x, P, (ht[p] - ht[q]) * NS_TO_S, hu[q, U_AX], hu[q, U_AY], prm)
        store_prior(hx, hc, p, x, P)
        fuse_stored(x, P, hz, p, prm)


@njit
def oldest_usable(ht: IntArray, meta: IntArray, prm: FloatArray, t_ns: int) -> int:
    """Return the slot for a sample at `t_ns`, or -1 if it is older than the history allows."""
    if t_ns < head_time(ht, meta) - int(prm[P_MAX_DELAY] * 1e9):
        return -1
    return find_slot(ht, meta, t_ns)


@njit
def history_slot(ht: IntArray, meta: IntArray, prm: FloatArray, t_ns: int) -> tuple[int, bool]:
    """Return ``(j, same_stamp)`` for a sample at `t_ns`, at or before the filter time.

    j is the logical slot at or before `t_ns`, -1 when the sample is too old (older
    than ``P_MAX_DELAY`` or than the oldest slot, or a new slot would go before the
    oldest of a full ring); same_stamp whether slot j has the sample's stamp.
    """
    j = oldest_usable(ht, meta, prm, t_ns)
    if j < 0:
        return -1, False
    k_len = ht.shape[0]
    same_stamp = ht[slot_index(meta, k_len, j)] == t_ns
    if not same_stamp and meta[M_COUNT] == k_len and j == 0:
        return -1, False
    return j, same_stamp
