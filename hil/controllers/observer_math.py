"""EKF math for the state observer: predict and update on plain float64 arrays, in place.

State vector, shape (9,), indexed by the ``I_*`` constants:

    x = [x_m, y_m, psi_rad, u_mps, v_mps, r_radps, b_ax_mps2, b_ay_mps2, b_r_radps]

The first six are the pose eta = (x, y, psi) in the arena frame and the body
velocities nu = (u, v, r); the last three are the IMU biases (accelerometer x, y
in the body frame, gyro z). With zero bias noise and zero initial bias variance
the bias states stay fixed and the filter is the plain six-state EKF. Noise,
gates and limits come in one parameter vector, ``P_*`` indexing.

Notes:
    Process model (continuous, Fossen 2021, Ch. 2, for the kinematics; the
    IMU as input as in the aided INS of Fossen 2021, Ch. 14), with the accelerometer
    measuring the body-frame specific force f = nu_dot + (-r v, r u):

        eta_dot = R(psi) nu
        u_dot   = (f_x - b_ax) + r v + w_u
        v_dot   = (f_y - b_ay) - r u + w_v
        r_dot   = w_r,   b_dot = w_b            (random walks)

    discretized with forward Euler over dt and the Jacobian J of the right-hand
    side at the prior, F = I + dt J, P <- F P F^T + Q dt with
    Q = diag(0, 0, 0, q_uv, q_uv, q_r, q_ba, q_ba, q_br) (Moore & Stouch 2014,
    robot_localization, which uses the same first-order transition and Q dt).
    Measurements: pose z = (x, y, psi) + v_p (heading innovation wrapped to
    [-pi, pi)) and gyro z = r + b_r + v_g. Update: S = H P H^T + R,
    d^2 = y^T S^-1 y compared with a chi-square gate, K = P H^T S^-1,
    x <- x + K y, P <- P - K S K^T, symmetrized (Simon 2006, Ch. 5 and 13).

    Why the IMU as input and why bias states: a constant-velocity random walk
    (robot_localization's default) needs a process noise large enough for
    thrust changes, which makes the velocity noisy or laggy; with the measured
    specific force as input the velocity follows the thrust at once. A constant
    accelerometer bias b would then leave a velocity offset of about
    sqrt(2) b / omega_n (omega_n the bandwidth of the pose loop: 0.02 m/s for
    b = 0.05 m/s^2), above the paper's tracking errors, so the biases are
    states, observable from 100 Hz poses within seconds.
"""

from __future__ import annotations

import math

from hil.core.arrays import FloatArray
from hil.core.geometry import wrap_angle
from hil.core.jit import njit

# State indices.
I_X = 0
I_Y = 1
I_PSI = 2
I_U = 3
I_V = 4
I_R = 5
I_BAX = 6
I_BAY = 7
I_BR = 8
N_STATE = 9

# Parameter vector indices (see ObserverConfig.params for units).
P_Q_UV = 0  # velocity random-walk intensity, (m/s)^2/s
P_Q_R = 1  # yaw-rate random-walk intensity, (rad/s)^2/s
P_Q_BA = 2  # accelerometer-bias random-walk intensity, (m/s^2)^2/s
P_Q_BR = 3  # gyro-bias random-walk intensity, (rad/s)^2/s
P_R_X = 4  # pose x variance, m^2
P_R_Y = 5  # pose y variance, m^2
P_R_PSI = 6  # heading variance, rad^2
P_R_GYRO = 7  # yaw-rate variance, (rad/s)^2
P_GATE_POSE = 8  # chi-square gate, 3 degrees of freedom
P_GATE_GYRO = 9  # chi-square gate, 1 degree of freedom
P_MAX_POS = 10  # largest believable |x|, |y|, m
P_MAX_ACC = 11  # largest believable |f_x|, |f_y|, m/s^2
P_MAX_RATE = 12  # largest believable |r|, rad/s
P_MAX_DELAY = 13  # oldest sample fused, s before the newest filter time
P_GATE_RESET = 14  # gated poses in a row that restart the filter (0: never)
P_RESTART_VAR_UV = 15  # u, v variance after a restart, (m/s)^2
P_RESTART_VAR_R = 16  # r variance after a restart, (rad/s)^2
P_RESTART_VAR_BA = 17  # accelerometer-bias variance after a restart, (m/s^2)^2
P_RESTART_VAR_BR = 18  # gyro-bias variance after a restart, (rad/s)^2
P_ACCEL_HOLD = 19  # longest span an accelerometer sample drives the prediction, s
N_PARAMS = 20


@njit
def ekf_predict(
    x: FloatArray, P: FloatArray, dt_s: float, accel_x: float, accel_y: float, params: FloatArray
) -> None:
    """Propagate over `dt_s` in place, holding the accelerometer sample for a bounded time.

    An accelerometer sample drives the prediction for at most ``params[P_ACCEL_HOLD]``
    seconds: if the IMU falls silent, a stale reading would otherwise push the
    velocity for as long as the gap lasts. Beyond the hold the body velocity is
    predicted constant (the specific force nu_dot = 0 implies, bias included).

    Args:
        x: State (9,), overwritten with the prior at t + dt.
        P: Covariance (9, 9), overwritten.
        dt_s: Step (s, >= 0).
        accel_x: Measured specific force along body x at the step's start (m/s^2).
        accel_y: Measured specific force along body y (m/s^2).
        params: Parameter vector (N_PARAMS,); uses ``P_Q_*`` and ``P_ACCEL_HOLD``.
    """
    hold = params[P_ACCEL_HOLD]
    if hold <= 0.0 or dt_s <= hold:
        _predict_step(x, P, dt_s, accel_x, accel_y, params)
        return
    _predict_step(x, P, hold, accel_x, accel_y, params)
    # f = nu_dot + (-r v, r u) + b with nu_dot = 0.
    r = x[I_R]
    _predict_step(x, P, dt_s - hold, x[I_BAX] - r * x[I_V], x[I_BAY] + r * x[I_U], params)


@njit
def _predict_step(
    x: FloatArray, P: FloatArray, dt_s: float, accel_x: float, accel_y: float, params: FloatArray
) -> None:
    """Propagate the state and covariance over `dt_s` with the input held, in place.

    Args:
        x: State (9,), overwritten with the prior at t + dt.
        P: Covariance (9, 9), overwritten with F P F^T + Q dt.
        dt_s: Step (s, >= 0).
        accel_x: Measured specific force along body x, held over the step (m/s^2).
        accel_y: Measured specific force along body y (m/s^2).
        params: Parameter vector (N_PARAMS,); uses the ``P_Q_*`` entries.

    Notes:
        F = I + dt J with J the Jacobian at the prior (module docstring). Only
        rows 0-4 of J are non-zero, so F P F^T is done in place without
        temporaries: P <- F P column by column (each new column depends on the
        old one only), then P <- P F^T row by row, then symmetrized.
    """
    psi = x[I_PSI]
    u = x[I_U]
    v = x[I_V]
    r = x[I_R]
    c = math.cos(psi)
    s = math.sin(psi)
    # Non-zero Jacobian entries besides the constants (J[2, 5] = 1, J[3, 6] = J[4, 7] = -1).
    j02 = dt_s * (-s * u - c * v)
    j03 = dt_s * c
    j04 = -dt_s * s
    j12 = dt_s * (c * u - s * v)
    j13 = dt_s * s
    j14 = dt_s * c
    j34 = dt_s * r
    j35 = dt_s * v
    j43 = -dt_s * r
    j45 = -dt_s * u
    # P <- F P: column k's rows 0..4 from the old column k.
    for k in range(N_STATE):
        p2 = P[I_PSI, k]
        p3 = P[I_U, k]
        p4 = P[I_V, k]
        p5 = P[I_R, k]
        P[I_X, k] += j02 * p2 + j03 * p3 + j04 * p4
        P[I_Y, k] += j12 * p2 + j13 * p3 + j14 * p4
        P[I_PSI, k] = p2 + dt_s * p5
        P[I_U, k] = p3 + j34 * p4 + j35 * p5 - dt_s * P[I_BAX, k]
        P[I_V, k] = p4 + j43 * p3 + j45 * p5 - dt_s * P[I_BAY, k]
    # P <- P F^T: row i's columns 0..4 from the old row i.
    for i in range(N_STATE):
        p2 = P[i, I_PSI]
        p3 = P[i, I_U]
        p4 = P[i, I_V]
        p5 = P[i, I_R]
        P[i, I_X] += j02 * p2 + j03 * p3 + j04 * p4
        P[i, I_Y] += j12 * p2 + j13 * p3 + j14 * p4
        P[i, I_PSI] = p2 + dt_s * p5
        P[i, I_U] = p3 + j34 * p4 + j35 * p5 - dt_s * P[i, I_BAX]
        P[i, I_V] = p4 + j43 * p3 + j45 * p5 - dt_s * P[i, I_BAY]
    for i in range(N_STATE):
        for j in range(i + 1, N_STATE):
            val = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = val
            P[j, i] = val
    P[I_U, I_U] += params[P_Q_UV] * dt_s
    P[I_V, I_V] += params[P_Q_UV] * dt_s
    P[I_R, I_R] += params[P_Q_R] * dt_s
    P[I_BAX, I_BAX] += params[P_Q_BA] * dt_s
    P[I_BAY, I_BAY] += params[P_Q_BA] * dt_s
    P[I_BR, I_BR] += params[P_Q_BR] * dt_s
    # State: forward Euler from the prior.
    du = (accel_x - x[I_BAX]) + r * v
    dv = (accel_y - x[I_BAY]) - r * u
    x[I_X] += dt_s * (c * u - s * v)
    x[I_Y] += dt_s * (s * u + c * v)
    x[I_PSI] = wrap_angle(psi + dt_s * r)
    x[I_U] = u + dt_s * du
    x[I_V] = v + dt_s * dv


@njit
def _s_inverse(
    P: FloatArray, rx: float, ry: float, rpsi: float
) -> tuple[bool, float, float, float, float, float, float]:
    """Return (ok, i00, i01, i02, i11, i12, i22): S^-1 of a pose, S = P[:3, :3] + R.

    By cofactors of the symmetric 3 x 3 S; ok is False when S is not positive
    definite (or not finite).
    """
    s00 = P[0, 0] + rx
    s11 = P[1, 1] + ry
    s22 = P[2, 2] + rpsi
    s01 = P[0, 1]
    s02 = P[0, 2]
    s12 = P[1, 2]
    c00 = s11 * s22 - s12 * s12
    c01 = s02 * s12 - s01 * s22
    c02 = s01 * s12 - s02 * s11
    det = s00 * c00 + s01 * c01 + s02 * c02
    if not (det > 0.0 and math.isfinite(det)):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    c11 = s00 * s22 - s02 * s02
    c12 = s01 * s02 - s00 * s12
    c22 = s00 * s11 - s01 * s01
    inv = 1.0 / det
    return True, c00 * inv, c01 * inv, c02 * inv, c11 * inv, c12 * inv, c22 * inv


@njit
def _innovation(
    x: FloatArray, P: FloatArray, zx: float, zy: float, zpsi: float,
    rx: float, ry: float, rpsi: float,
) -> tuple[bool, float, float, float, float, float, float, float, float, float, float]:
    """Return (ok, y0, y1, y2, i00, i01, i02, i11, i12, i22, d2) of a finite pose z.

    y = z - H x (y_psi wrapped), the entries of S^-1 (:func:`_s_inverse`) and
    d2 = y^T S^-1 y; ok False (d2 inf) when S is not positive definite.
    """
    y0 = zx - x[I_X]
    y1 = zy - x[I_Y]
    y2 = wrap_angle(zpsi - x[I_PSI])
    ok, i00, i01, i02, i11, i12, i22 = _s_inverse(P, rx, ry, rpsi)
    if not ok:
        return False, y0, y1, y2, i00, i01, i02, i11, i12, i22, math.inf
    w0 = i00 * y0 + i01 * y1 + i02 * y2
    w1 = i01 * y0 + i11 * y1 + i12 * y2
    w2 = i02 * y0 + i12 * y1 + i22 * y2
    return True, y0, y1, y2, i00, i01, i02, i11, i12, i22, y0 * w0 + y1 * w1 + y2 * w2


@njit
def pose_innovation(
    x: FloatArray,
    P: FloatArray,
    zx: float,
    zy: float,
    zpsi: float,
    rx: float,
    ry: float,
    rpsi: float,
    out: FloatArray,
) -> None:
    """Write a pose's innovation against the prior (x, P) to out, shape (3,).

    out[0]: the normalized innovation squared y^T S^-1 y (the gate's d^2; chi-square
    with 3 dof for a consistent filter; inf when S is not positive definite);
    out[1]: |(y_x, y_y)| (m); out[2]: |y_psi| (rad, wrapped). NaN for a non-finite z.
    """
    if not (math.isfinite(zx) and math.isfinite(zy) and math.isfinite(zpsi)):
        out[0] = out[1] = out[2] = math.nan
        return
    _, y0, y1, y2, _, _, _, _, _, _, d2 = _innovation(x, P, zx, zy, zpsi, rx, ry, rpsi)
    out[0] = d2
    out[1] = math.sqrt(y0 * y0 + y1 * y1)
    out[2] = abs(y2)


@njit
def ekf_update_pose(
    x: FloatArray, P: FloatArray, z: FloatArray, r_diag: FloatArray, gate_chi2: float
) -> bool:
    """Fuse a pose measurement z = (x, y, psi), in place; refuse it if gated.

    Args:
        x: State (9,), updated in place when accepted.
        P: Covariance (9, 9), updated in place when accepted.
        z: Measured (x_m, y_m, psi_rad), shape (3,).
        r_diag: Measurement variances (m^2, m^2, rad^2), shape (3,).
        gate_chi2: Largest accepted Mahalanobis distance squared (3 dof).

    Returns:
        True if fused; False (x and P untouched) if z is not finite, S is not
        positive definite, or d^2 > gate_chi2.

    Notes:
        H = [I_3 0]; y = z - H x with y_psi wrapped; S = P[:3, :3] + R;
        K = P[:, :3] S^-1; P <- P - K S K^T = P - P[:, :3] K^T.
    """
    return _update_pose(x, P, z[0], z[1], z[2], r_diag[0], r_diag[1], r_diag[2], gate_chi2)


@njit
def _update_pose(
    x: FloatArray,
    P: FloatArray,
    zx: float,
    zy: float,
    zpsi: float,
    rx: float,
    ry: float,
    rpsi: float,
    gate_chi2: float,
) -> bool:
    """Do :func:`ekf_update_pose` on scalars (no temporary arrays for z and R)."""
    if not (math.isfinite(zx) and math.isfinite(zy) and math.isfinite(zpsi)):
        return False
    ok, y0, y1, y2, i00, i01, i02, i11, i12, i22, d2 = _innovation(
        x, P, zx, zy, zpsi, rx, ry, rpsi
    )
    if not ok or not (d2 <= gate_chi2):
        return False
    # K = PH S^-1 with PH = P[:, :3]. x first; then only the upper triangle of P
    # is written, row by row: P[i, j] -= K_i . PH_j, where PH_j = P[j, :3] for
    # j >= i still reads original entries (lower triangle or rows not yet
    # written); mirrored at the end. No temporary array.
    for i in range(N_STATE):
        p0 = P[i, 0]
        p1 = P[i, 1]
        p2 = P[i, 2]
        k0 = p0 * i00 + p1 * i01 + p2 * i02
        k1 = p0 * i01 + p1 * i11 + p2 * i12
        k2 = p0 * i02 + p1 * i12 + p2 * i22
        x[i] += k0 * y0 + k1 * y1 + k2 * y2
    x[I_PSI] = wrap_angle(x[I_PSI])
    for i in range(N_STATE):
        p0 = P[i, 0]
        p1 = P[i, 1]
        p2 = P[i, 2]
        k0 = p0 * i00 + p1 * i01 + p2 * i02
        k1 = p0 * i01 + p1 * i11 + p2 * i12
        k2 = p0 * i02 + p1 * i12 + p2 * i22
        for j in range(i, N_STATE):
            P[i, j] -= k0 * P[j, 0] + k1 * P[j, 1] + k2 * P[j, 2]
    for i in range(N_STATE):
        for j in range(i + 1, N_STATE):
            P[j, i] = P[i, j]
    return True


@njit
def ekf_update_yaw_rate(
    x: FloatArray, P: FloatArray, z_radps: float, r_var: float, gate_chi2: float
) -> bool:
    """Fuse a gyro reading z = r + b_r, in place; refuse it if gated.

    Args:
        x: State (9,), updated in place when accepted.
        P: Covariance (9, 9), updated in place when accepted.
        z_radps: Measured yaw rate (rad/s).
        r_var: Measurement variance ((rad/s)^2).
        gate_chi2: Largest accepted y^2 / S (1 dof).

    Returns:
        True if fused; False (x and P untouched) if z is not finite or gated.

    Notes:
        H = e_r + e_br; S = P_rr + 2 P_r,br + P_br,br + R; K = (P[:, r] + P[:, br]) / S.
    """
    if not math.isfinite(z_radps):
        return False
    y = z_radps - (x[I_R] + x[I_BR])
    s = P[I_R, I_R] + 2.0 * P[I_R, I_BR] + P[I_BR, I_BR] + r_var
    if not (s > 0.0 and math.isfinite(s)):
        return False
    if not (y * y <= gate_chi2 * s):
        return False
    # K = ph / S with ph = P[:, r] + P[:, br]. x first; then only the upper
    # triangle of P is written, row by row, so ph_j = P[j, r] + P[j, br] for
    # j >= i still reads original entries (lower triangle or rows not yet
    # written); mirrored at the end. No temporary array.
    inv = 1.0 / s
    for i in range(N_STATE):
        x[i] += (P[i, I_R] + P[i, I_BR]) * inv * y
    for i in range(N_STATE):
        ph_i = P[i, I_R] + P[i, I_BR]
        for j in range(i, N_STATE):
            ph_j = P[j, I_R] + P[j, I_BR]
            P[i, j] -= ph_i * ph_j * inv
    for i in range(N_STATE):
        for j in range(i + 1, N_STATE):
            P[j, i] = P[i, j]
    return True
