"""3-DOF dynamics kernels: ``M nu_dot + C(nu) nu + D(nu) nu = tau + b`` and its integrators.

Small ``@njit`` kernels on plain arrays (:func:`coriolis_matrix`,
:func:`damping_matrix`, :func:`acceleration`, :func:`euler_step`, :func:`rk4_step`,
:func:`integrate_step`); :class:`~hil.model.vessel.Vessel`, the plant in
:mod:`hil.sim.plant` and the closed loop in :mod:`hil.sim.closed_loop` all call them,
so there is one copy of the physics.

States: ``eta = (x, y, psi)`` in the world frame (m, m, rad, heading wrapped to
[-pi, pi)), ``nu = (u, v, r)`` in the body frame (m/s, m/s, rad/s). Forces ``tau`` and
loads ``b`` are ``(X, Y, N)`` in N, N, N m. Body frame x forward, y starboard, z down.
The parameters come as ``m_inv`` (3, 3) and ``coef`` (N_COEF,) from
:meth:`~hil.model.coefficients.VesselParams.kernel_arrays`.
"""

from __future__ import annotations

import enum
import math

import numpy as np

from hil.core.arrays import FloatArray
from hil.core.geometry import wrap_angle
from hil.core.jit import njit
from hil.model.coefficients import (
    I_DAMPING_ON,
    I_M,
    I_NR,
    I_NRR,
    I_NRRR,
    I_NRV,
    I_NV,
    I_NVR,
    I_NVV,
    I_NVVV,
    I_XG,
    I_XU,
    I_XUD,
    I_XUU,
    I_XUUU,
    I_YR,
    I_YRD,
    I_YRR,
    I_YRRR,
    I_YRV,
    I_YV,
    I_YVD,
    I_YVR,
    I_YVV,
    I_YVVV,
)

__all__ = [
    "Integrator",
    "acceleration",
    "coriolis_matrix",
    "coriolis_terms",
    "damping_matrix",
    "damping_terms",
    "euler_step",
    "hydro_force",
    "hydro_terms",
    "integrate_step",
    "rk4_step",
    "simulate_kernel",
]


class Integrator(enum.IntEnum):
    """Time integrators of the model; the value is what the kernels receive."""

    EULER = 0
    """Forward Euler, as in the paper and the lab's simulator (dt = 0.01 s)."""
    RK4 = 1
    """Classical 4th-order Runge-Kutta, force held constant over the step."""


_RK4 = int(Integrator.RK4)  # the kernels take the value: a global int is a compile-time constant


@njit
def coriolis_terms(coef: FloatArray, nu: FloatArray) -> tuple[float, float]:
    """Return (c13, c23) of C(nu) (see :func:`coriolis_matrix`)."""
    m = coef[I_M]
    c13 = (-m * coef[I_XG] + coef[I_YRD]) * nu[2] + (-m + coef[I_YVD]) * nu[1]
    c23 = (m - coef[I_XUD]) * nu[0]
    return c13, c23


@njit
def damping_terms(coef: FloatArray, nu: FloatArray) -> tuple[float, float, float, float, float]:
    """Return (d11, d22, d23, d32, d33) of D(nu) (see :func:`damping_matrix`)."""
    if coef[I_DAMPING_ON] == 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    au = abs(nu[0])
    av = abs(nu[1])
    ar = abs(nu[2])
    d11 = -coef[I_XU] - coef[I_XUU] * au - coef[I_XUUU] * nu[0] * nu[0]
    d22 = -coef[I_YV] - coef[I_YVV] * av - coef[I_YVVV] * nu[1] * nu[1] - coef[I_YRV] * ar
    d23 = -coef[I_YR] - coef[I_YRR] * ar - coef[I_YRRR] * nu[2] * nu[2] - coef[I_YVR] * av
    d32 = -coef[I_NV] - coef[I_NVV] * av - coef[I_NVVV] * nu[1] * nu[1] - coef[I_NRV] * ar
    d33 = -coef[I_NR] - coef[I_NRR] * ar - coef[I_NRRR] * nu[2] * nu[2] - coef[I_NVR] * av
    return d11, d22, d23, d32, d33


@njit
def coriolis_matrix(coef: FloatArray, nu: FloatArray) -> FloatArray:
    """Return C(nu) = C_RB + C_A, shape (3, 3), skew-symmetric.

    Notes:
        c13 = (-m xg + Y_rdot) r + (-m + Y_vdot) v, c23 = (m - X_udot) u,
        C = [[0, 0, c13], [0, 0, c23], [-c13, -c23, 0]] (Fossen 2021, Eq. 6.43/6.53).
    """
    c13, c23 = coriolis_terms(coef, nu)
    out = np.zeros((3, 3))
    out[0, 2] = c13
    out[1, 2] = c23
    out[2, 0] = -c13
    out[2, 1] = -c23
    return out


@njit
def damping_matrix(coef: FloatArray, nu: FloatArray) -> FloatArray:
    """Return D(nu), shape (3, 3), in the textbook form of :class:`VesselParams`."""
    d11, d22, d23, d32, d33 = damping_terms(coef, nu)
    out = np.zeros((3, 3))
    out[0, 0] = d11
    out[1, 1] = d22
    out[1, 2] = d23
    out[2, 1] = d32
    out[2, 2] = d33
    return out


@njit
def hydro_terms(coef: FloatArray, nu: FloatArray) -> tuple[float, float, float]:
    """Return C(nu) nu + D(nu) nu as three scalars (N, N, N m); allocation-free."""
    c13, c23 = coriolis_terms(coef, nu)
    d11, d22, d23, d32, d33 = damping_terms(coef, nu)
    u, v, r = nu[0], nu[1], nu[2]
    return (
        c13 * r + d11 * u,
        c23 * r + d22 * v + d23 * r,
        -c13 * u - c23 * v + d32 * v + d33 * r,
    )


@njit
def hydro_force(coef: FloatArray, nu: FloatArray) -> FloatArray:
    """Return C(nu) nu + D(nu) nu, shape (3,) (N, N, N m): the force to hold nu steady."""
    h0, h1, h2 = hydro_terms(coef, nu)
    out = np.empty(3)
    out[0] = h0
    out[1] = h1
    out[2] = h2
    return out


@njit
def acceleration(
    m_inv: FloatArray, coef: FloatArray, nu: FloatArray, force: FloatArray
) -> FloatArray:
    """Return nu_dot = M^-1 (force - C(nu) nu - D(nu) nu), shape (3,).

    Args:
        m_inv: Inverse inertia matrix, shape (3, 3).
        coef: Coefficient array, shape (N_COEF,).
        nu: Body velocities (u, v, r), shape (3,).
        force: tau + b, shape (3,) (N, N, N m).
    """
    h0, h1, h2 = hydro_terms(coef, nu)
    f0 = force[0] - h0
    f1 = force[1] - h1
    f2 = force[2] - h2
    out = np.empty(3)
    for i in range(3):
        out[i] = m_inv[i, 0] * f0 + m_inv[i, 1] * f1 + m_inv[i, 2] * f2
    return out


@njit
def _eta_rate(psi: float, nu: FloatArray) -> tuple[float, float]:
    c = math.cos(psi)
    s = math.sin(psi)
    return c * nu[0] - s * nu[1], s * nu[0] + c * nu[1]


@njit
def euler_step(
    m_inv: FloatArray,
    coef: FloatArray,
    eta: FloatArray,
    nu: FloatArray,
    force: FloatArray,
    dt: float,
) -> tuple[FloatArray, FloatArray]:
    """Advance one forward-Euler step (paper, Sec. IV); return new ``(eta, nu)``, (3,) each.

    Notes:
        eta[k+1] = eta[k] + dt R(psi[k]) nu[k]; nu[k+1] = nu[k] + dt nu_dot[k]; psi wrapped.
    """
    return euler_advance(eta, nu, acceleration(m_inv, coef, nu, force), dt)


@njit
def euler_advance(
    eta: FloatArray, nu: FloatArray, nu_dot: FloatArray, dt: float
) -> tuple[FloatArray, FloatArray]:
    """Advance one forward-Euler step from a known acceleration; return ``(eta, nu)``.

    The plant already evaluates ``nu_dot`` for its accelerometer; passing it in spares
    a second evaluation per step (:func:`euler_step` is this with ``nu_dot`` computed).

    Args:
        eta: Pose (x m, y m, psi rad), shape (3,).
        nu: Body velocity (u m/s, v m/s, r rad/s), shape (3,).
        nu_dot: Its derivative at (nu, force), shape (3,).
        dt: Step (s).
    """
    xd, yd = _eta_rate(eta[2], nu)
    eta_new = np.empty(3)
    eta_new[0] = eta[0] + dt * xd
    eta_new[1] = eta[1] + dt * yd
    eta_new[2] = wrap_angle(eta[2] + dt * nu[2])
    nu_new = np.empty(3)
    for i in range(3):
        nu_new[i] = nu[i] + dt * nu_dot[i]
    return eta_new, nu_new


@njit
def rk4_step(
    m_inv: FloatArray,
    coef: FloatArray,
    eta: FloatArray,
    nu: FloatArray,
    force: FloatArray,
    dt: float,
) -> tuple[FloatArray, FloatArray]:
    """Advance one classical RK4 step with the force held; return new ``(eta, nu)``.

    The heading is integrated unwrapped inside the step and wrapped at the end.
    """
    k1v = acceleration(m_inv, coef, nu, force)
    k1x, k1y = _eta_rate(eta[2], nu)
    k1p = nu[2]
    nu2 = nu + 0.5 * dt * k1v
    psi2 = eta[2] + 0.5 * dt * k1p
    k2v = acceleration(m_inv, coef, nu2, force)
    k2x, k2y = _eta_rate(psi2, nu2)
    k2p = nu2[2]
    nu3 = nu + 0.5 * dt * k2v
    psi3 = eta[2] + 0.5 * dt * k2p
    k3v = acceleration(m_inv, coef, nu3, force)
    k3x, k3y = _eta_rate(psi3, nu3)
    k3p = nu3[2]
    nu4 = nu + dt * k3v
    psi4 = eta[2] + dt * k3p
    k4v = acceleration(m_inv, coef, nu4, force)
    k4x, k4y = _eta_rate(psi4, nu4)
    k4p = nu4[2]
    w = dt / 6.0
    eta_new = np.empty(3)
    eta_new[0] = eta[0] + w * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
    eta_new[1] = eta[1] + w * (k1y + 2.0 * k2y + 2.0 * k3y + k4y)
    eta_new[2] = wrap_angle(eta[2] + w * (k1p + 2.0 * k2p + 2.0 * k3p + k4p))
    nu_new = nu + w * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
    return eta_new, nu_new


@njit
def integrate_step(
    m_inv: FloatArray,
    coef: FloatArray,
    eta: FloatArray,
    nu: FloatArray,
    force: FloatArray,
    dt: float,
    method: int,
) -> tuple[FloatArray, FloatArray]:
    """Advance one step with ``method`` (an :class:`Integrator` value)."""
    if method == _RK4:
        return rk4_step(m_inv, coef, eta, nu, force, dt)
    return euler_step(m_inv, coef, eta, nu, force, dt)


@njit
def simulate_kernel(
    m_inv: FloatArray,
    coef: FloatArray,
    eta0: FloatArray,
    nu0: FloatArray,
    force: FloatArray,
    dt: float,
    method: int,
) -> tuple[FloatArray, FloatArray]:
    """Integrate under a force series; return ``(eta, nu)``, each (N + 1, 3), time-major.

    Args:
        m_inv: Inverse inertia matrix, shape (3, 3).
        coef: Coefficient array, shape (N_COEF,).
        eta0: Initial pose, shape (3,).
        nu0: Initial body velocity, shape (3,).
        force: tau + b per step, shape (N, 3), held over each step.
        dt: Step (s).
        method: An :class:`Integrator` value.
    """
    n = force.shape[0]
    etas = np.empty((n + 1, 3))
    nus = np.empty((n + 1, 3))
    etas[0] = eta0
    nus[0] = nu0
    eta = eta0.copy()
    nu = nu0.copy()
    for k in range(n):
        eta, nu = integrate_step(m_inv, coef, eta, nu, force[k], dt, method)
        etas[k + 1] = eta
        nus[k + 1] = nu
    return etas, nus
