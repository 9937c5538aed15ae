"""3-DOF vessel model of C/S Enterprise I: ``M nu_dot + C(nu) nu + D(nu) nu = tau + b``.

The math lives in small ``@njit`` kernels on plain arrays (:func:`coriolis_matrix`,
:func:`damping_matrix`, :func:`acceleration`, :func:`euler_step`, :func:`rk4_step`,
:func:`integrate_step`); :class:`Vessel` and the closed loop in
:mod:`hil.sim.closed_loop` both call them, so there is one copy of the physics.

States: ``eta = (x, y, psi)`` in the world frame (m, m, rad, heading wrapped to
[-pi, pi)), ``nu = (u, v, r)`` in the body frame (m/s, m/s, rad/s). Forces ``tau`` and
loads ``b`` are ``(X, Y, N)`` in N, N, N m. Body frame x forward, y starboard, z down.

Kernels take the parameters as two arrays built by :meth:`VesselParams.kernel_arrays`:
``m_inv`` (3, 3), the inverse inertia matrix, and ``coef`` (N_COEF,), the coefficients
indexed by the ``I_*`` constants below.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from hil.core.geometry import wrap_angle
from hil.core.jit import njit
from hil.model.environment import EnvironmentalLoad
from hil.model.errors import NonFiniteForceError, StateShapeError, VesselConfigError

FloatArray = NDArray[np.float64]

__all__ = [
    "ENTERPRISE_I",
    "N_COEF",
    "EnvironmentalLoad",
    "Integrator",
    "Vessel",
    "VesselParams",
    "VesselState",
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

# Layout of the `coef` array the kernels read.
I_M = 0
I_XG = 1
I_XUD = 2
I_YVD = 3
I_YRD = 4
I_XU = 5
I_XUU = 6
I_XUUU = 7
I_YV = 8
I_YVV = 9
I_YVVV = 10
I_YR = 11
I_YRR = 12
I_YRRR = 13
I_YRV = 14
I_YVR = 15
I_NV = 16
I_NVV = 17
I_NVVV = 18
I_NR = 19
I_NRR = 20
I_NRRR = 21
I_NRV = 22
I_NVR = 23
I_DAMPING_ON = 24
N_COEF = 25


class Integrator(enum.IntEnum):
    """Time integrators of the model; the value is what the kernels receive."""

    EULER = 0
    """Forward Euler, as in the paper and the lab's simulator (dt = 0.01 s)."""
    RK4 = 1
    """Classical 4th-order Runge-Kutta, force held constant over the step."""


@dataclass(frozen=True, slots=True)
class VesselParams:
    """Rigid-body, added-mass and damping coefficients (Fossen notation, SI units).

    Defaults are C/S Enterprise I (Skåtun 2011, as used by the lab's simulator
    ``cybership_enterprise1.py``). Damping uses the usual form for this set:

        d11 = -Xu - Xuu|u| - Xuuu u^2
        d22 = -Yv - Yvv|v| - Yvvv v^2 - Yrv|r|
        d23 = -Yr - Yrr|r| - Yrrr r^2 - Yvr|v|
        d32 = -Nv - Nvv|v| - Nvvv v^2 - Nrv|r|
        d33 = -Nr - Nrr|r| - Nrrr r^2 - Nvr|v|

    The lab's file differs: it computes d33 = -Nr - Nvr|v| - Nrrr r^2 (no Nrr term)
    and d32 = -Nv - Nvvv|v| - Nr v^2 - Nrv|r| (indices shifted by one into the N
    array, so Nr multiplies v^2); that looks like an indexing bug, so the textbook
    form is used here. Xvv is listed by the lab but unused in d11 by either form.

    Note:
        With these coefficients D is not dissipative in the strict sense:
        d23 = -Yr = 7.25 exceeds 2 sqrt(d22 d33), so nu^T D(nu) nu < 0 where v and r
        have opposite signs (about -0.159 at (0, -0.2, 0.4)). The model is still
        stable: M^-1 D(0) has eigenvalues with positive real parts (0.041, 0.061,
        0.628 1/s) and a free coast decays to rest.

    Attributes:
        m_kg: Rigid-body mass (kg).
        iz_kgm2: Yaw moment of inertia about the body origin (kg m^2).
        xg_m: Longitudinal position of the centre of gravity (m).
        x_udot: Added mass X_udot (kg), negative.
        y_vdot: Added mass Y_vdot (kg).
        y_rdot: Added mass Y_rdot (kg m).
        n_vdot: Added mass N_vdot (kg m).
        n_rdot: Added inertia N_rdot (kg m^2).
        xu, xuu, xuuu: Surge damping (N s/m, N s^2/m^2, N s^3/m^3).
        yv, yvv, yvvv, yr, yrr, yrrr, yrv, yvr: Sway damping coefficients.
        nv, nvv, nvvv, nr, nrr, nrrr, nrv, nvr: Yaw damping coefficients.
        damping_enabled: False switches D off (for energy-conservation checks).
    """

    m_kg: float = 14.11
    iz_kgm2: float = 1.76
    xg_m: float = 0.0375
    x_udot: float = -2.0
    y_vdot: float = -10.0
    y_rdot: float = 0.0
    n_vdot: float = 0.0
    n_rdot: float = -1.0
    xu: float = -0.6555
    xuu: float = 0.3545
    xuuu: float = -3.787
    yv: float = -1.3443
    yvv: float = -2.776
    yvvv: float = -65.91
    yr: float = -7.25
    yrr: float = -3.45
    yrrr: float = 0.0
    yrv: float = -0.805
    yvr: float = -0.845
    nv: float = 0.0
    nvv: float = -0.2088
    nvvv: float = 0.0
    nr: float = -1.9
    nrr: float = -0.75
    nrrr: float = 0.0
    nrv: float = 0.130
    nvr: float = 0.080
    damping_enabled: bool = True

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if isinstance(value, float) and not math.isfinite(value):
                raise VesselConfigError(f"vessel parameter {name} must be finite, got {value!r}")
        if self.m_kg <= 0.0:
            raise VesselConfigError(f"mass m_kg must be positive, got {self.m_kg!r}")
        if self.iz_kgm2 <= 0.0:
            raise VesselConfigError(f"inertia iz_kgm2 must be positive, got {self.iz_kgm2!r}")
        m = self.mass_matrix()
        if not np.allclose(m, m.T, rtol=0.0, atol=1e-12):
            raise VesselConfigError(
                f"inertia matrix M must be symmetric (y_rdot == n_vdot), got "
                f"y_rdot={self.y_rdot!r}, n_vdot={self.n_vdot!r}"
            )
        eig = np.linalg.eigvalsh(m)
        if eig[0] <= 0.0:
            raise VesselConfigError(
                f"inertia matrix M is not positive definite (eigenvalues {eig.tolist()!r}): "
                f"M = {m.tolist()!r}"
            )

    def mass_matrix(self) -> FloatArray:
        """Return M = M_RB + M_A, shape (3, 3), over (u, v, r)."""
        m, xg = self.m_kg, self.xg_m
        return np.array(
            [
                [m - self.x_udot, 0.0, 0.0],
                [0.0, m - self.y_vdot, m * xg - self.y_rdot],
                [0.0, m * xg - self.n_vdot, self.iz_kgm2 - self.n_rdot],
            ]
        )

    def kernel_arrays(self) -> tuple[FloatArray, FloatArray]:
        """Return ``(m_inv (3, 3), coef (N_COEF,))``, the arrays the kernels read."""
        coef = np.zeros(N_COEF)
        coef[I_M] = self.m_kg
        coef[I_XG] = self.xg_m
        coef[I_XUD] = self.x_udot
        coef[I_YVD] = self.y_vdot
        coef[I_YRD] = self.y_rdot
        values = (
            self.xu, self.xuu, self.xuuu,
            self.yv, self.yvv, self.yvvv, self.yr, self.yrr, self.yrrr, self.yrv, self.yvr,
            self.nv, self.nvv, self.nvvv, self.nr, self.nrr, self.nrrr, self.nrv, self.nvr,
        )  # fmt: skip
        coef[I_XU : I_NVR + 1] = values
        coef[I_DAMPING_ON] = 1.0 if self.damping_enabled else 0.0
        m_inv = np.asarray(np.linalg.inv(self.mass_matrix()), dtype=np.float64)
        return m_inv, coef


ENTERPRISE_I = VesselParams()
"""The paper's simulation model, C/S Enterprise I."""


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
    a = acceleration(m_inv, coef, nu, force)
    xd, yd = _eta_rate(eta[2], nu)
    eta_new = np.empty(3)
    eta_new[0] = eta[0] + dt * xd
    eta_new[1] = eta[1] + dt * yd
    eta_new[2] = wrap_angle(eta[2] + dt * nu[2])
    nu_new = np.empty(3)
    for i in range(3):
        nu_new[i] = nu[i] + dt * a[i]
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
    if method == 1:
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


def _as_vec3(name: str, value: object) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,):
        raise StateShapeError(f"{name} must have shape (3,), got {arr.shape!r}")
    if not np.all(np.isfinite(arr)):
        raise StateShapeError(f"{name} must be finite, got {arr.tolist()!r}")
    return arr


def _check_force(name: str, value: object) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape[-1:] != (3,) or arr.ndim not in (1, 2):
        raise StateShapeError(f"{name} must have shape (3,) or (N, 3), got {arr.shape!r}")
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise NonFiniteForceError(
            f"{name} has a non-finite entry at index {tuple(bad.tolist())!r}: {arr[tuple(bad)]!r}"
        )
    return arr


@dataclass(frozen=True, slots=True)
class VesselState:
    """Pose and body velocity.

    Attributes:
        eta: (x, y, psi), shape (3,), world frame (m, m, rad in [-pi, pi)).
        nu: (u, v, r), shape (3,), body frame (m/s, m/s, rad/s).
    """

    eta: FloatArray
    nu: FloatArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "eta", _as_vec3("eta", self.eta))
        object.__setattr__(self, "nu", _as_vec3("nu", self.nu))

    @staticmethod
    def at_rest(x_m: float = 0.0, y_m: float = 0.0, psi_rad: float = 0.0) -> VesselState:
        """Return a state at the given pose with zero velocity."""
        return VesselState(np.array([x_m, y_m, wrap_angle(psi_rad)]), np.zeros(3))


@dataclass(frozen=True)
class Vessel:
    """The simulated vessel: parameters, integrator and step; stateless.

    Attributes:
        params: Model coefficients.
        dt_s: Integration step (s); 0.01 s is the paper's.
        integrator: Forward Euler (the paper's) or RK4.
    """

    params: VesselParams = ENTERPRISE_I
    dt_s: float = 0.01
    integrator: Integrator = Integrator.EULER
    _arrays: tuple[FloatArray, FloatArray] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt_s) and self.dt_s > 0.0):
            raise VesselConfigError(f"dt_s must be positive and finite, got {self.dt_s!r}")
        object.__setattr__(self, "_arrays", self.params.kernel_arrays())

    def acceleration(
        self, nu: FloatArray, tau: FloatArray, b: FloatArray | None = None
    ) -> FloatArray:
        """Return nu_dot, shape (3,), for body velocity ``nu`` under ``tau + b`` (N, N, N m).

        Raises:
            NonFiniteForceError: If ``tau`` or ``b`` holds NaN or inf.
        """
        force = _check_force("tau", tau) + (np.zeros(3) if b is None else _check_force("b", b))
        m_inv, coef = self._arrays
        return acceleration(m_inv, coef, _as_vec3("nu", nu), force)

    def step(self, state: VesselState, tau: FloatArray, b: FloatArray | None = None) -> VesselState:
        """Advance one step of ``dt_s`` under thrust ``tau`` and load ``b``, shape (3,) each.

        Raises:
            NonFiniteForceError: If ``tau`` or ``b`` holds NaN or inf.
        """
        force = _check_force("tau", tau) + (np.zeros(3) if b is None else _check_force("b", b))
        m_inv, coef = self._arrays
        eta, nu = integrate_step(
            m_inv, coef, state.eta, state.nu, force, self.dt_s, int(self.integrator)
        )
        return VesselState(eta, nu)

    def simulate(
        self, state: VesselState, tau: FloatArray, b: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Integrate over a force series.

        Args:
            state: Initial state.
            tau: Thrust per step, shape (N, 3) (N, N, N m), held over each step.
            b: Environmental load per step, shape (N, 3), or None for zero.

        Returns:
            ``(eta, nu)``, each shape (N + 1, 3), time-major; row 0 is ``state``.

        Raises:
            NonFiniteForceError: If ``tau`` or ``b`` holds NaN or inf.
        """
        tau_arr = _check_force("tau", tau)
        if tau_arr.ndim != 2:
            raise StateShapeError(f"tau must have shape (N, 3), got {tau_arr.shape!r}")
        force = tau_arr if b is None else tau_arr + _check_force("b", b)
        m_inv, coef = self._arrays
        return simulate_kernel(
            m_inv,
            coef,
            state.eta,
            state.nu,
            np.ascontiguousarray(force),
            self.dt_s,
            int(self.integrator),
        )
