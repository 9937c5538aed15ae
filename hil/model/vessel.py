"""The simulated vessel: :class:`Vessel` steps a :class:`VesselState` under thrust and load.

The Python face of :mod:`hil.model.dynamics`: it checks shapes and finiteness, then
calls the same kernels the compiled loops use. States: ``eta = (x, y, psi)`` in the
world frame (m, m, rad in [-pi, pi)), ``nu = (u, v, r)`` in the body frame (m/s, m/s,
rad/s); forces ``(X, Y, N)`` in N, N, N m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hil.core.arrays import FloatArray, finite_vector
from hil.core.geometry import wrap_angle
from hil.model.coefficients import ENTERPRISE_I, VesselParams
from hil.model.dynamics import Integrator, acceleration, integrate_step, simulate_kernel
from hil.model.errors import NonFiniteForceError, StateShapeError, VesselConfigError

__all__ = ["Vessel", "VesselState"]


def _as_vec3(name: str, value: object) -> FloatArray:
    return finite_vector(name, value, 3, StateShapeError, StateShapeError)


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
