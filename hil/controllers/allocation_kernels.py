"""Compiled thrust-allocation kernels on the extended thrust formulation.

Each azimuth contributes two columns (its force components fx, fy), the tunnel one
(fy), so ``tau = B_e xi`` with a constant (3, 5) matrix ``B_e`` and
``xi = (f_tunnel, f_port_x, f_port_y, f_stbd_x, f_stbd_y)`` in newtons (Fossen 2021,
Sec. 11.2.2). Commands follow as ``u_i = |f_i| / K_i`` and ``alpha_i = atan2(fy, fx)``.
The allocator classes in :mod:`hil.controllers.allocation` and the compiled closed
loop (:mod:`hil.sim.closed_loop`) call these same kernels.
"""

from __future__ import annotations

import math

import numpy as np

from hil.core.arrays import FloatArray
from hil.core.geometry import wrap_angle
from hil.core.jit import njit
from hil.model.thrusters import T_K_TUNNEL, T_LX_PORT, T_LX_TUNNEL, T_LY_PORT, T_UMAX_TUNNEL

__all__ = [
    "N_XI",
    "bounded_least_squares",
    "extended_matrix",
    "force_limits",
    "is_feasible",
    "matvec",
    "mma_allocate",
    "null_space_gradient",
    "project_feasible",
    "pseudo_inverse_allocate",
    "xi_to_commands",
]

N_XI = 5
"""Length of the extended force vector xi."""


@njit
def extended_matrix(tp: FloatArray) -> FloatArray:
    """Return B_e, shape (3, 5), the constant extended configuration matrix.

    Notes:
        Columns: tunnel fy [0, 1, lx_t]; for each azimuth at (lx, ly) fx [1, 0, -ly]
        and fy [0, 1, lx] (moment N = lx fy - ly fx).
    """
    out = np.zeros((3, N_XI))
    out[1, 0] = 1.0
    out[2, 0] = tp[T_LX_TUNNEL]
    for j in range(2):
        lx = tp[T_LX_PORT + 2 * j]
        ly = tp[T_LY_PORT + 2 * j]
        out[0, 1 + 2 * j] = 1.0
        out[2, 1 + 2 * j] = -ly
        out[1, 2 + 2 * j] = 1.0
        out[2, 2 + 2 * j] = lx
    return out


@njit
def force_limits(tp: FloatArray) -> FloatArray:
    """Return the largest force per thruster (tunnel, port, starboard), (3,) (N)."""
    out = np.empty(3)
    for j in range(3):
        out[j] = tp[T_K_TUNNEL + j] * tp[T_UMAX_TUNNEL + j]
    return out


@njit
def matvec(a: FloatArray, x: FloatArray) -> FloatArray:
    """Return a @ x for a small matrix (n, m) and vector (m,) with plain loops.

    For 3x5-sized operands this beats the BLAS call numba makes for ``@``.
    """
    n, m = a.shape
    out = np.zeros(n)
    for i in range(n):
        acc = 0.0
        for j in range(m):
            acc += a[i, j] * x[j]
        out[i] = acc
    return out


@njit
def _project_in_place(x: FloatArray, fmax: FloatArray) -> None:
    x[0] = min(max(x[0], -fmax[0]), fmax[0])
    for j in range(2):
        fx = x[1 + 2 * j]
        fy = x[2 + 2 * j]
        mag = math.sqrt(fx * fx + fy * fy)
        if mag > fmax[1 + j]:
            s = fmax[1 + j] / mag
            x[1 + 2 * j] = fx * s
            x[2 + 2 * j] = fy * s


@njit
def project_feasible(xi: FloatArray, fmax: FloatArray) -> FloatArray:
    """Return the nearest xi within the limits: tunnel clipped, azimuth forces scaled."""
    out = xi.copy()
    _project_in_place(out, fmax)
    return out


@njit
def is_feasible(xi: FloatArray, fmax: FloatArray, tol: float) -> bool:
    """Return whether xi is within the limits up to ``tol`` (N)."""
    if abs(xi[0]) > fmax[0] + tol:
        return False
    for j in range(2):
        fx = xi[1 + 2 * j]
        fy = xi[2 + 2 * j]
        if math.sqrt(fx * fx + fy * fy) > fmax[1 + j] + tol:
            return False
    return True


@njit
def _normal_equations(
    be: FloatArray, tau: FloatArray, wq: FloatArray, reg: float
) -> tuple[FloatArray, FloatArray]:
    """Return ``(H, g)``: H = B_e^T W^2 B_e + reg I, shape (5, 5); g = B_e^T W^2 tau, (5,)."""
    h = np.zeros((N_XI, N_XI))
    g = np.zeros(N_XI)
    for a in range(N_XI):
        for i in range(3):
            wsq = wq[i] * wq[i]
            g[a] += be[i, a] * wsq * tau[i]
            for b in range(N_XI):
                h[a, b] += be[i, a] * wsq * be[i, b]
        h[a, a] += reg
    return h, g


@njit
def _gradient_lipschitz(be: FloatArray, wq: FloatArray, reg: float) -> float:
    """Return L = lambda_max(B_e^T W^2 B_e) + reg, the gradient's Lipschitz constant.

    lambda_max(B^T W^2 B) = lambda_max(W B B^T W), a 3x3 matrix: power iteration in
    scalars (no allocation in the loop; 40 steps are ample for the step size).
    """
    sm = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for a in range(N_XI):
                acc += be[i, a] * be[j, a]
            sm[i, j] = wq[i] * acc * wq[j]
    v0, v1, v2 = 1.0, 1.0, 1.0
    lip = 1.0
    for _ in range(40):
        w0 = sm[0, 0] * v0 + sm[0, 1] * v1 + sm[0, 2] * v2
        w1 = sm[1, 0] * v0 + sm[1, 1] * v1 + sm[1, 2] * v2
        w2 = sm[2, 0] * v0 + sm[2, 1] * v1 + sm[2, 2] * v2
        lip = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        v0, v1, v2 = w0 / lip, w1 / lip, w2 / lip
    return lip + reg


@njit
def _gradient_step(
    h: FloatArray, g: FloatArray, y: FloatArray, step: float, grad: FloatArray, x_new: FloatArray
) -> None:
    """Write grad = H y - g and x_new = y - step * grad (both (5,), in place)."""
    for a in range(N_XI):
        acc = -g[a]
        for b in range(N_XI):
            acc += h[a, b] * y[b]
        grad[a] = acc
        x_new[a] = y[a] - step * acc


@njit
def _points_uphill(grad: FloatArray, x_new: FloatArray, x: FloatArray) -> bool:
    """Return whether the step x -> x_new goes up the gradient (grad . (x_new - x) > 0)."""
    uphill = 0.0
    for a in range(N_XI):
        uphill += grad[a] * (x_new[a] - x[a])
    return uphill > 0.0


@njit
def _accept_step(x: FloatArray, x_new: FloatArray, y: FloatArray, beta: float) -> float:
    """Move x to x_new and y to x_new + beta (x_new - x), in place; return max |x_new - x| (N)."""
    moved = 0.0
    for a in range(N_XI):
        d = x_new[a] - x[a]
        moved = max(moved, abs(d))
        y[a] = x_new[a] + beta * d
        x[a] = x_new[a]
    return moved


@njit
def bounded_least_squares(
    be: FloatArray,
    tau: FloatArray,
    fmax: FloatArray,
    xi0: FloatArray,
    wq: FloatArray,
    reg: float,
    iterations: int,
) -> FloatArray:
    """Minimize 0.5 |W (B_e xi - tau)|^2 + 0.5 reg |xi|^2 over feasible xi (FISTA).

    Args:
        be: Extended configuration matrix, shape (3, 5).
        tau: Demand, shape (3,).
        fmax: Force limits (tunnel, port, starboard), shape (3,).
        xi0: Start, shape (5,) (projected first).
        wq: Residual weights W (diagonal), shape (3,).
        reg: Small Tikhonov weight that picks the least-magnitude minimizer.
        iterations: Most accelerated projected-gradient steps (it stops earlier once
            an iterate moves less than 1e-13 N).

    Returns:
        xi, shape (5,), feasible.

    Notes:
        Beck & Teboulle (2009) FISTA with the constant step 1 / L,
        L = lambda_max(B_e^T W^2 B_e) + reg, and gradient restarts.
    """
    h, g = _normal_equations(be, tau, wq, reg)
    step = 1.0 / (_gradient_lipschitz(be, wq, reg) * 1.01)
    x = project_feasible(xi0, fmax)
    y = x.copy()
    x_new = np.empty(N_XI)
    grad = np.empty(N_XI)
    t = 1.0
    for _ in range(iterations):
        _gradient_step(h, g, y, step, grad, x_new)
        _project_in_place(x_new, fmax)
        # Gradient restart (O'Donoghue & Candes 2015): drop the momentum when it
        # points uphill, which makes the convergence linear near the solution.
        if _points_uphill(grad, x_new, x):
            t = 1.0
        t_new = 0.5 * (1.0 + math.sqrt(1.0 + 4.0 * t * t))
        moved = _accept_step(x, x_new, y, (t - 1.0) / t_new)
        t = t_new
        if moved < 1e-13:  # converged (to rounding) before the iteration cap
            break
    return x


@njit
def xi_to_commands(
    tp: FloatArray, xi: FloatArray, alpha_hold: FloatArray, eps: float
) -> tuple[FloatArray, FloatArray]:
    """Return ``(u (3,), alpha (2,))`` from xi, turning each azimuth at most 90 deg.

    An azimuth force f becomes (|f| / K, atan2(fy, fx)) or, where that angle is more
    than 90 deg from ``alpha_hold`` (the last angle), the same force with reversed
    thrust (-|f| / K, atan2(fy, fx) + pi). An azimuth below ``eps`` N keeps its angle.
    """
    u = np.empty(3)
    alpha = np.empty(2)
    u[0] = xi[0] / tp[T_K_TUNNEL]
    for j in range(2):
        fx = xi[1 + 2 * j]
        fy = xi[2 + 2 * j]
        mag = math.sqrt(fx * fx + fy * fy)
        u[1 + j] = mag / tp[T_K_TUNNEL + 1 + j]
        if mag > eps:
            angle = math.atan2(fy, fx)
            # Reversing the propeller beats slewing the pod more than 90 deg round.
            if abs(wrap_angle(angle - alpha_hold[j])) > 0.5 * math.pi:
                angle = wrap_angle(angle + math.pi)
                u[1 + j] = -u[1 + j]
            alpha[j] = angle
        else:
            alpha[j] = alpha_hold[j]
    # Guard the limits against rounding in the division.
    for j in range(3):
        lim = tp[T_UMAX_TUNNEL + j]
        u[j] = min(max(u[j], -lim), lim)
    return u, alpha


@njit
def pseudo_inverse_allocate(
    tp: FloatArray, b_pinv: FloatArray, tau: FloatArray, alpha_hold: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Plain pseudo-inverse with per-thruster clipping; return ``(u, alpha, xi)``."""
    xi = project_feasible(matvec(b_pinv, tau), force_limits(tp))
    u, alpha = xi_to_commands(tp, xi, alpha_hold, 1e-9)
    return u, alpha, xi


@njit
def null_space_gradient(
    xi: FloatArray, a_ref: FloatArray, weights: FloatArray, lam: float, eps: float
) -> FloatArray:
    """Return dJ/dxi, shape (5,), for the magnitude-and-azimuth cost.

    Notes:
        J = w_t sqrt(f_t^2 + eps^2) + sum_j w_j (sqrt(|f_j|^2 + eps^2) - lam a_ref_j . f_j),
        a smoothed form of the cost in Gezer et al. (2024): small thrust, azimuth
        forces pointing along their reference directions ``a_ref`` (2, 2), unit rows.
    """
    out = np.empty(N_XI)
    out[0] = weights[0] * xi[0] / math.sqrt(xi[0] * xi[0] + eps * eps)
    for j in range(2):
        fx = xi[1 + 2 * j]
        fy = xi[2 + 2 * j]
        n = math.sqrt(fx * fx + fy * fy + eps * eps)
        out[1 + 2 * j] = weights[1 + j] * (fx / n - lam * a_ref[j, 0])
        out[2 + 2 * j] = weights[1 + j] * (fy / n - lam * a_ref[j, 1])
    return out


@njit
def mma_allocate(
    tp: FloatArray,
    be: FloatArray,
    b_pinv: FloatArray,
    q: FloatArray,
    theta: FloatArray,
    tau: FloatArray,
    alpha_hold: FloatArray,
    cfg: FloatArray,
    a_ref: FloatArray,
    weights: FloatArray,
    wq: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """One minimum-magnitude-and-azimuth allocation; return ``(u, alpha, xi, theta)``.

    Args:
        tp: Thruster parameter array.
        be: B_e, shape (3, 5).
        b_pinv: Weighted pseudo-inverse of B_e, shape (5, 3).
        q: Orthonormal null-space basis of B_e, shape (5, 2).
        theta: Null-space parameter, shape (2,) (N).
        tau: Demand (X, Y, N), shape (3,).
        alpha_hold: Angles to keep for an azimuth with (almost) no thrust, (2,).
        cfg: (gamma N/s, lambda, eps N, dt s, iterations, reg), shape (6,).
        a_ref: Reference thrust directions (port, starboard), unit rows, (2, 2).
        weights: Cost weights (tunnel, port, starboard), shape (3,).
        wq: Residual weights for the saturated case, shape (3,).

    Notes:
        xi = B_w^+ tau + Q theta, theta <- theta - dt gamma Q^T dJ/dxi (Gezer et al.
        2024, the steepest-descent law on the null-space parameter). If xi leaves the
        envelope but B_w^+ tau fits, theta shrinks until xi fits (tau exact);
        otherwise :func:`bounded_least_squares` from there, and theta is re-fitted to
        the feasible solution's null-space part so the state does not wind up.
    """
    gamma = cfg[0]
    lam = cfg[1]
    eps = cfg[2]
    dt = cfg[3]
    fmax = force_limits(tp)
    xi_p = matvec(b_pinv, tau)
    xi = xi_p + matvec(q, theta)
    grad = null_space_gradient(xi, a_ref, weights, lam, eps)
    theta_new = theta - dt * gamma * matvec(q.T, grad)
    xi = xi_p + matvec(q, theta_new)
    if not is_feasible(xi, fmax, 0.0):
        if is_feasible(xi_p, fmax, 0.0):
            # The demand itself fits: keep as much of the null-space term as fits
            # (bisection on the segment xi_p + s Q theta, s in [0, 1]); exact tau.
            lo = 0.0
            hi = 1.0
            qt = matvec(q, theta_new)
            for _ in range(30):
                mid = 0.5 * (lo + hi)
                if is_feasible(xi_p + mid * qt, fmax, 0.0):
                    lo = mid
                else:
                    hi = mid
            theta_new = lo * theta_new
            xi = xi_p + lo * qt
        else:
            xi = bounded_least_squares(be, tau, fmax, xi, wq, cfg[5], int(cfg[4]))
            theta_new = matvec(q.T, xi)
    u, alpha = xi_to_commands(tp, xi, alpha_hold, 1e-9)
    return u, alpha, xi, theta_new
