"""EKF event kernels: samples in any order, through a ring buffer of past priors.

:func:`obs_init` and :func:`obs_pose` (and :func:`hil.controllers.observer_imu.obs_imu`)
work on an :class:`~hil.controllers.observer_arrays.EkfArrays` bundle: the current estimate plus
a ring buffer of the prior, the held accelerometer input and the measurements at each
past sample time, so a late or out-of-order sample is fused at its own time stamp and
the filter is re-run forward to the newest time (robot_localization's
``smooth_lagged_data``). They return an ``S_*`` status code and count every outcome in
``counters`` (:mod:`hil.controllers.observer_arrays`). The math (predict, updates,
state layout, parameter vector) is in :mod:`hil.controllers.observer_math`, the ring
bookkeeping in :mod:`hil.controllers.observer_ring`.
"""

from __future__ import annotations

import math

import numpy as np

from hil.controllers.observer_arrays import (
    C_NOT_INITIALIZED,
    C_POSE_ABSURD,
    C_POSE_DUPLICATE,
    C_POSE_FUSED,
    C_POSE_GATED,
    C_POSE_LATE,
    C_POSE_NONFINITE,
    C_POSE_RESET,
    C_POSE_TOO_OLD,
    NOT_REFUSED,
    S_ABSURD,
    S_DUPLICATE,
    S_FUSED,
    S_GATED,
    S_NONFINITE,
    S_NOT_INITIALIZED,
    S_RESET,
    S_TOO_OLD,
    EkfArrays,
)
from hil.controllers.observer_math import (
    I_BAX,
    I_BAY,
    I_BR,
    I_PSI,
    I_R,
    I_U,
    I_V,
    I_X,
    I_Y,
    N_STATE,
    P_GATE_POSE,
    P_GATE_RESET,
    P_MAX_POS,
    P_R_PSI,
    P_R_X,
    P_R_Y,
    P_RESTART_VAR_BA,
    P_RESTART_VAR_BR,
    P_RESTART_VAR_R,
    P_RESTART_VAR_UV,
    _update_pose,
    ekf_predict,
    pose_innovation,
)
from hil.controllers.observer_ring import (
    M_COUNT,
    M_GATED_RUN,
    M_INIT,
    M_START,
    NS_TO_S,
    U_AX,
    U_AY,
    Z_PSI,
    Z_X,
    Z_Y,
    fuse_stored,
    head_time,
    history_slot,
    insert_slot,
    load_prior,
    make_room,
    prior_at,
    propagate,
    rerun,
    slot_index,
    store_prior,
)
from hil.core.arrays import FloatArray, IntArray
from hil.core.geometry import wrap_angle
from hil.core.jit import njit

__all__ = ["obs_init", "obs_pose", "obs_predicted", "obs_time_ns"]


@njit
def obs_init(a: EkfArrays, t_ns: int, x0: FloatArray, P0: FloatArray) -> None:
    """Start (or restart) the filter at `t_ns` with state x0 (9,) and covariance P0 (9, 9).

    The history is cleared; the counters are kept.
    """
    a.meta[M_START] = 0
    a.meta[M_COUNT] = 1
    a.meta[M_INIT] = 1
    a.meta[M_GATED_RUN] = 0
    a.hist_t_ns[0] = t_ns
    a.x[:] = x0
    a.x[I_PSI] = wrap_angle(x0[I_PSI])
    a.P[:, :] = P0
    store_prior(a.hist_x, a.hist_cov, 0, a.x, a.P)
    a.hist_u[0, :] = 0.0
    a.hist_z[0, :] = np.nan


@njit
def obs_time_ns(a: EkfArrays) -> int:
    """Return the filter time (ns): the stamp of the newest sample fused, or -1 before init."""
    if a.meta[M_INIT] == 0:
        return -1
    return head_time(a.hist_t_ns, a.meta)


@njit
def obs_predicted(a: EkfArrays, t_ns: int, x_out: FloatArray, P_out: FloatArray) -> bool:
    """Write the estimate extrapolated to `t_ns` into x_out (9,), P_out (9, 9); change nothing.

    The held accelerometer input carries on from the filter time, as it would if
    no sample arrived before `t_ns`: for a control step between samples.

    Returns:
        False (outputs untouched) before the filter starts or if `t_ns` is before
        the filter time.
    """
    if a.meta[M_INIT] == 0:
        return False
    t_head = head_time(a.hist_t_ns, a.meta)
    if t_ns < t_head:
        return False
    head = slot_index(a.meta, a.hist_t_ns.shape[0], a.meta[M_COUNT] - 1)
    x_out[:] = a.x
    P_out[:, :] = a.P
    if t_ns > t_head:
        dt_s = (t_ns - t_head) * NS_TO_S
        ekf_predict(x_out, P_out, dt_s, a.hist_u[head, U_AX], a.hist_u[head, U_AY], a.params)
    return True


# The kernels below take the EkfArrays fields one by one (x, P, ht = hist_t_ns,
# hx = hist_x, hc = hist_cov, hu = hist_u, hz = hist_z, meta, c = counters,
# prm = params, innov = innovation): a helper taking the bundle increfs all eleven
# arrays per call, which measurably slows the per-sample path.


@njit
def _restart_at_pose(
    x: FloatArray,
    P: FloatArray,
    ht: IntArray,
    hx: FloatArray,
    hc: FloatArray,
    hu: FloatArray,
    hz: FloatArray,
    meta: IntArray,
    prm: FloatArray,
    x_m: float,
    y_m: float,
    psi: float,
) -> None:
    """Restart the filter from a pose: eta from it, nu and the biases kept, one slot left.

    eta is set to the pose at the filter time (a late pose's age is ignored: at most
    the latency's worth of motion) and P to diag(R_pose, restart variances of nu and
    the biases).
    """
    head = slot_index(meta, ht.shape[0], meta[M_COUNT] - 1)
    x[I_X] = x_m
    x[I_Y] = y_m
    x[I_PSI] = psi
    for i in range(N_STATE):
        for j in range(N_STATE):
            P[i, j] = 0.0
    P[I_X, I_X] = prm[P_R_X]
    P[I_Y, I_Y] = prm[P_R_Y]
    P[I_PSI, I_PSI] = prm[P_R_PSI]
    P[I_U, I_U] = prm[P_RESTART_VAR_UV]
    P[I_V, I_V] = prm[P_RESTART_VAR_UV]
    P[I_R, I_R] = prm[P_RESTART_VAR_R]
    P[I_BAX, I_BAX] = prm[P_RESTART_VAR_BA]
    P[I_BAY, I_BAY] = prm[P_RESTART_VAR_BA]
    P[I_BR, I_BR] = prm[P_RESTART_VAR_BR]
    if head != 0:
        ht[0] = ht[head]
        for col in range(3):
            hu[0, col] = hu[head, col]
    for col in range(4):
        hz[0, col] = np.nan
    store_prior(hx, hc, 0, x, P)
    meta[M_START] = 0
    meta[M_COUNT] = 1
    meta[M_GATED_RUN] = 0


@njit
def _gated(
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
    x_m: float,
    y_m: float,
    psi: float,
) -> int:
    """Count a gated pose; after P_GATE_RESET in a row, restart the filter from this one.

    Persistent disagreement between 1 mm poses and the prediction means the
    prediction is wrong (a jump in accelerometer bias from tilt, a wrong start),
    and gating on would let the dead reckoning run away (see :func:`_restart_at_pose`).
    """
    meta[M_GATED_RUN] += 1
    limit = prm[P_GATE_RESET]
    if limit <= 0.0 or meta[M_GATED_RUN] < limit:
        c[C_POSE_GATED] += 1
        return S_GATED
    _restart_at_pose(x, P, ht, hx, hc, hu, hz, meta, prm, x_m, y_m, psi)
    c[C_POSE_RESET] += 1
    return S_RESET


@njit
def _refuse_pose(
    meta: IntArray, c: IntArray, prm: FloatArray, x_m: float, y_m: float, psi_rad: float
) -> int:
    """Return the counted ``S_*`` code of a pose refused whatever its stamp, else NOT_REFUSED.

    Refused: a value not finite, a position beyond ``P_MAX_POS``, a filter not started.
    """
    if not (math.isfinite(x_m) and math.isfinite(y_m) and math.isfinite(psi_rad)):
        c[C_POSE_NONFINITE] += 1
        return S_NONFINITE
    if abs(x_m) > prm[P_MAX_POS] or abs(y_m) > prm[P_MAX_POS]:
        c[C_POSE_ABSURD] += 1
        return S_ABSURD
    if meta[M_INIT] == 0:
        c[C_NOT_INITIALIZED] += 1
        return S_NOT_INITIALIZED
    return NOT_REFUSED


@njit
def obs_pose(a: EkfArrays, t_ns: int, x_m: float, y_m: float, psi_rad: float) -> int:
    """Fuse a pose measured at `t_ns`, in order, late or out of order.

    Args:
        a: Filter arrays, updated in place.
        t_ns: Measurement time stamp (ns), may be before the filter time.
        x_m: Measured x (m, arena frame).
        y_m: Measured y (m).
        psi_rad: Measured heading (rad, any branch).

    Returns:
        ``S_FUSED``, or the ``S_*`` reason it was refused (state untouched then);
        the matching counter is incremented. ``S_RESET`` when it was the
        ``P_GATE_RESET``-th gated pose in a row and restarted the filter.

    Notes:
        A sample stamped before the filter time is placed in the history at its
        stamp (a slot is opened if none has that stamp), its gate is checked on the
        prior there, and the filter is re-run forward through the stored inputs and
        measurements: the result equals fusing it on time (Moore & Stouch 2014,
        ``smooth_lagged_data``). Older than ``P_MAX_DELAY`` or than the oldest slot:
        refused as too old.
    """
    return _pose_event(a.x, a.P, a.hist_t_ns, a.hist_x, a.hist_cov, a.hist_u, a.hist_z, a.meta,
                       a.counters, a.params, a.innovation, t_ns, x_m, y_m, psi_rad)


@njit
def _pose_event(
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
    innov: FloatArray,
    t_ns: int,
    x_m: float,
    y_m: float,
    psi_rad: float,
) -> int:
    """Do :func:`obs_pose` on the arrays one by one: refuse it, or fuse it where it belongs."""
    innov[0] = innov[1] = innov[2] = math.nan
    refused = _refuse_pose(meta, c, prm, x_m, y_m, psi_rad)
    if refused != NOT_REFUSED:
        return refused
    j, same_stamp = history_slot(ht, meta, prm, t_ns)
    if j < 0:
        c[C_POSE_TOO_OLD] += 1
        return S_TOO_OLD
    p = slot_index(meta, ht.shape[0], j)
    if same_stamp and not math.isnan(hz[p, Z_X]):
        c[C_POSE_DUPLICATE] += 1
        return S_DUPLICATE
    late = t_ns < head_time(ht, meta)
    psi = wrap_angle(psi_rad)
    if not same_stamp:
        return _fuse_pose_in_new_slot(x, P, ht, hx, hc, hu, hz, meta, c, prm, innov, j, t_ns,
                                      x_m, y_m, psi, late)
    if j < meta[M_COUNT] - 1:
        return _fuse_pose_at_stored_stamp(x, P, ht, hx, hc, hu, hz, meta, c, prm, innov, j,
                                          x_m, y_m, psi, late)
    # At the filter time: the posterior is updated in place.
    if not _update_with_pose(x, P, prm, innov, x_m, y_m, psi):
        return _gated(x, P, ht, hx, hc, hu, hz, meta, c, prm, x_m, y_m, psi)
    _store_pose(hz, p, x_m, y_m, psi)
    return _pose_fused(meta, c, late)


@njit
def _update_with_pose(
    x: FloatArray,
    P: FloatArray,
    prm: FloatArray,
    innov: FloatArray,
    x_m: float,
    y_m: float,
    psi: float,
) -> bool:
    """Write the pose's innovation against (x, P) to innov (3,), then fuse it into (x, P).

    Returns:
        Whether the pose passed its gate ((x, P) untouched when not).
    """
    rx, ry, rpsi = prm[P_R_X], prm[P_R_Y], prm[P_R_PSI]
    pose_innovation(x, P, x_m, y_m, psi, rx, ry, rpsi, innov)
    return _update_pose(x, P, x_m, y_m, psi, rx, ry, rpsi, prm[P_GATE_POSE])


@njit
def _store_pose(hz: FloatArray, p: int, x_m: float, y_m: float, psi: float) -> None:
    """Record a fused pose in ring slot `p` (physical index) of the measurements (K, 4)."""
    hz[p, Z_X] = x_m
    hz[p, Z_Y] = y_m
    hz[p, Z_PSI] = psi


@njit
def _fuse_pose_at_stored_stamp(
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
    innov: FloatArray,
    j: int,
    x_m: float,
    y_m: float,
    psi: float,
    late: bool,
) -> int:
    """Fuse a late pose at logical slot j, a stamp the history has (the usual latency case).

    Re-run from that slot with the gate checked there; refused, the saved posterior
    comes back bit for bit (no later slot was touched yet).
    """
    p = slot_index(meta, ht.shape[0], j)
    x_save = x.copy()
    P_save = P.copy()
    load_prior(hx, hc, p, x, P)
    fuse_stored(x, P, hz, p, prm)
    if not _update_with_pose(x, P, prm, innov, x_m, y_m, psi):
        x[:] = x_save
        P[:, :] = P_save
        return _gated(x, P, ht, hx, hc, hu, hz, meta, c, prm, x_m, y_m, psi)
    _store_pose(hz, p, x_m, y_m, psi)
    propagate(x, P, ht, hx, hc, hu, hz, meta, prm, j)
    return _pose_fused(meta, c, late)


@njit
def _fuse_pose_in_new_slot(
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
    innov: FloatArray,
    j: int,
    t_ns: int,
    x_m: float,
    y_m: float,
    psi: float,
    late: bool,
) -> int:
    """Fuse a pose at a stamp the history lacks, after logical slot j: a slot opens there.

    The gate is checked on the prior at `t_ns`; fused, the filter is re-run from the
    new slot (or, the new slot being the newest, the posterior is the fused prior).
    """
    xs = np.empty(N_STATE)
    Ps = np.empty((N_STATE, N_STATE))
    prior_at(x, P, ht, hx, hc, hu, hz, meta, prm, j, t_ns, xs, Ps)
    xg = xs.copy()
    Pg = Ps.copy()
    if not _update_with_pose(xg, Pg, prm, innov, x_m, y_m, psi):
        return _gated(x, P, ht, hx, hc, hu, hz, meta, c, prm, x_m, y_m, psi)
    q = make_room(meta, ht.shape[0], j) + 1
    p = insert_slot(ht, hx, hc, hu, hz, meta, q, t_ns)
    store_prior(hx, hc, p, xs, Ps)
    _store_pose(hz, p, x_m, y_m, psi)
    if q == meta[M_COUNT] - 1:
        x[:] = xg
        P[:, :] = Pg
    else:
        rerun(x, P, ht, hx, hc, hu, hz, meta, prm, q)
    return _pose_fused(meta, c, late)


@njit
def _pose_fused(meta: IntArray, c: IntArray, late: bool) -> int:
    """Count a fused pose and end a run of gated ones."""
    meta[M_GATED_RUN] = 0
    c[C_POSE_FUSED] += 1
    if late:
        c[C_POSE_LATE] += 1
    return S_FUSED
