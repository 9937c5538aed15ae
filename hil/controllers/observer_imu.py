"""EKF IMU event kernel: an IMU sample in any order, through the ring of past priors.

:func:`obs_imu` advances the filter to the sample's time, holds its accelerations as the
input from then on and fuses its yaw rate; a late sample is fused at its own stamp in the
history and the filter is re-run forward (as a late pose is in
:mod:`hil.controllers.observer_kernels`). It returns an ``S_*`` status code and counts
every outcome (:mod:`hil.controllers.observer_arrays`).
"""

from __future__ import annotations

import math

import numpy as np

from hil.controllers.observer_arrays import (
    C_GYRO_GATED,
    C_IMU_ABSURD,
    C_IMU_DUPLICATE,
    C_IMU_FUSED,
    C_IMU_LATE,
    C_IMU_NONFINITE,
    C_IMU_TOO_OLD,
    C_NOT_INITIALIZED,
    NOT_REFUSED,
    S_ABSURD,
    S_DUPLICATE,
    S_FUSED,
    S_GATED,
    S_NONFINITE,
    S_NOT_INITIALIZED,
    S_TOO_OLD,
    EkfArrays,
)
from hil.controllers.observer_math import (
    N_STATE,
    P_GATE_GYRO,
    P_MAX_ACC,
    P_MAX_RATE,
    P_R_GYRO,
    ekf_predict,
    ekf_update_yaw_rate,
)
from hil.controllers.observer_ring import (
    M_COUNT,
    M_INIT,
    NS_TO_S,
    U_AX,
    U_AY,
    U_OWN,
    Z_R,
    head_time,
    history_slot,
    insert_slot,
    make_room,
    prior_at,
    rerun,
    slot_index,
    store_prior,
)
from hil.core.arrays import FloatArray, IntArray
from hil.core.jit import njit

__all__ = ["obs_imu"]


@njit
def _refuse_imu(
    meta: IntArray, c: IntArray, prm: FloatArray, accel_x: float, accel_y: float, yaw_rate: float
) -> int:
    """Return the counted ``S_*`` code of an IMU sample refused whatever its stamp.

    Refused: a value not finite, an acceleration beyond ``P_MAX_ACC`` or a rate beyond
    ``P_MAX_RATE``, a filter not started. Else NOT_REFUSED.
    """
    if not (math.isfinite(accel_x) and math.isfinite(accel_y) and math.isfinite(yaw_rate)):
        c[C_IMU_NONFINITE] += 1
        return S_NONFINITE
    max_acc = prm[P_MAX_ACC]
    if abs(accel_x) > max_acc or abs(accel_y) > max_acc or abs(yaw_rate) > prm[P_MAX_RATE]:
        c[C_IMU_ABSURD] += 1
        return S_ABSURD
    if meta[M_INIT] == 0:
        c[C_NOT_INITIALIZED] += 1
        return S_NOT_INITIALIZED
    return NOT_REFUSED


@njit
def obs_imu(a: EkfArrays, t_ns: int, accel_x: float, accel_y: float, yaw_rate: float) -> int:
    """Take an IMU sample at `t_ns`: advance the filter, hold its accelerations, fuse its rate.

    Args:
        a: Filter arrays, updated in place.
        t_ns: Measurement time stamp (ns); usually after the filter time, which
            it advances; earlier stamps are fused in the history like late poses.
        accel_x: Specific force along body x (m/s^2), the input from t_ns on.
        accel_y: Specific force along body y (m/s^2).
        yaw_rate: Gyro z (rad/s).

    Returns:
        ``S_FUSED``; ``S_GATED`` when the accelerations were taken but the yaw rate
        failed its gate; or the ``S_*`` reason the whole sample was refused (state
        untouched). The matching counter is incremented.
    """
    return _imu_event(a.x, a.P, a.hist_t_ns, a.hist_x, a.hist_cov, a.hist_u, a.hist_z, a.meta,
                      a.counters, a.params, t_ns, accel_x, accel_y, yaw_rate)


@njit
def _imu_event(
    x: FloatArray,
    P: FloatArray,
    ht: IntArray,
    hx: FloatArray,
    hc: FloatArray,
    hu: FloatArray,
    hz: FloatArray,
    meta: IntArray,
    c: IntArray,
    prm: FloatArray,
    t_ns: int,
    accel_x: float,
    accel_y: float,
    yaw_rate: float,
) -> int:
    """Do :func:`obs_imu` on the arrays one by one: refuse it, or take it where it belongs."""
    refused = _refuse_imu(meta, c, prm, accel_x, accel_y, yaw_rate)
    if refused != NOT_REFUSED:
        return refused
    t_head = head_time(ht, meta)
    if t_ns > t_head:
        # Fast path: predict the posterior in place and open a slot at t_ns.
        k_len = ht.shape[0]
        head = slot_index(meta, k_len, meta[M_COUNT] - 1)
        ekf_predict(x, P, (t_ns - t_head) * NS_TO_S, hu[head, U_AX], hu[head, U_AY], prm)
        make_room(meta, k_len, 0)
        p = insert_slot(ht, hx, hc, hu, hz, meta, meta[M_COUNT], t_ns)
        store_prior(hx, hc, p, x, P)
        _hold_input(hu, p, accel_x, accel_y)
        gyro_ok = ekf_update_yaw_rate(x, P, yaw_rate, prm[P_R_GYRO], prm[P_GATE_GYRO])
        if gyro_ok:
            hz[p, Z_R] = yaw_rate
        return _imu_fused(c, False, gyro_ok)
    j, same_stamp = history_slot(ht, meta, prm, t_ns)
    if j < 0:
        c[C_IMU_TOO_OLD] += 1
        return S_TOO_OLD
    if same_stamp and hu[slot_index(meta, ht.shape[0], j), U_OWN] == 1.0:
        c[C_IMU_DUPLICATE] += 1
        return S_DUPLICATE
    return _imu_in_history(x, P, ht, hx, hc, hu, hz, meta, c, prm, j, same_stamp, t_ns,
                           t_ns < t_head, accel_x, accel_y, yaw_rate)


@njit
def _hold_input(hu: FloatArray, p: int, accel_x: float, accel_y: float) -> None:
    """Hold an IMU sample's accelerations from ring slot `p` (physical index), its own."""
    hu[p, U_AX] = accel_x
    hu[p, U_AY] = accel_y
    hu[p, U_OWN] = 1.0


@njit
def _imu_fused(c: IntArray, late: bool, gyro_ok: bool) -> int:
    """Count an IMU sample taken (late or not, its rate gated or not); return its status."""
    c[C_IMU_FUSED] += 1
    if late:
        c[C_IMU_LATE] += 1
    if not gyro_ok:
        c[C_GYRO_GATED] += 1
        return S_GATED
    return S_FUSED


@njit
def _imu_in_history(
    x: FloatArray,
    P: FloatArray,
    ht: IntArray,
    hx: FloatArray,
    hc: FloatArray,
    hu: FloatArray,
    hz: FloatArray,
    meta: IntArray,
    c: IntArray,
    prm: FloatArray,
    j: int,
    same_stamp: bool,
    t_ns: int,
    late: bool,
    accel_x: float,
    accel_y: float,
    yaw_rate: float,
) -> int:
    """Take an IMU sample at or before the filter time, at or after logical slot j.

    Its accelerations hold from its slot (opened if none has its stamp) up to the
    next IMU sample of its own; the rate is gated on the prior there and the filter
    re-run forward from the slot.
    """
    xs = np.empty(N_STATE)
    Ps = np.empty((N_STATE, N_STATE))
    prior_at(x, P, ht, hx, hc, hu, hz, meta, prm, j, t_ns, xs, Ps)
    xg = xs.copy()
    Pg = Ps.copy()
    gyro_ok = ekf_update_yaw_rate(xg, Pg, yaw_rate, prm[P_R_GYRO], prm[P_GATE_GYRO])
    k_len = ht.shape[0]
    if same_stamp:
        q = j
        p = slot_index(meta, k_len, j)
    else:
        q = make_room(meta, k_len, j) + 1
        p = insert_slot(ht, hx, hc, hu, hz, meta, q, t_ns)
        store_prior(hx, hc, p, xs, Ps)
    _hold_input(hu, p, accel_x, accel_y)
    for logical in range(q + 1, meta[M_COUNT]):  # up to the next sample of its own
        pl = slot_index(meta, k_len, logical)
        if hu[pl, U_OWN] == 1.0:
            break
        hu[pl, U_AX] = accel_x
        hu[pl, U_AY] = accel_y
    if gyro_ok:
        hz[p, Z_R] = yaw_rate
    if q == meta[M_COUNT] - 1:  # same stamp as the head (a later one took the fast path)
        if gyro_ok:
            x[:] = xg
            P[:, :] = Pg
    else:
        rerun(x, P, ht, hx, hc, hu, hz, meta, prm, q)
    return _imu_fused(c, late, gyro_ok)
