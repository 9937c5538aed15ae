"""Thrust allocation: generalized force (X, Y, N) -> thruster commands and azimuth angles.

Two allocators behind one :class:`Allocator` protocol, both on the extended thrust
formulation (Fossen 2021, Sec. 11.2.2): each azimuth contributes two columns (its
force components fx, fy), the tunnel one (fy), so ``tau = B_e xi`` with a constant
(3, 5) matrix ``B_e`` and ``xi = (f_tunnel, f_port_x, f_port_y, f_stbd_x, f_stbd_y)``
in newtons. Commands follow as ``u_i = |f_i| / K_i`` and ``alpha_i = atan2(fy, fx)``.

* :class:`PseudoInverseAllocator`: ``xi = B_e^+ tau``, each thruster then clipped to
  its limit (what the lab's simulator uses, ``skadipy.allocator.PseudoInverse``).
* :class:`MinimumMagnitudeAzimuthAllocator`: the method of the lab's
  ``skadipy`` ``MinimumMagnitudeAndAzimuth`` (Gezer et al., "Maneuvering-based dynamic
  thrust allocation", IFAC 2024), written here: a weighted pseudo-inverse solution plus
  a null-space term ``Q theta`` whose parameter follows gradient descent on a cost
  that minimizes magnitude and pulls each azimuth toward its reference angle; a
  demand outside the thrust envelope is met as closely as possible by a bounded
  least-squares solve (accelerated projected gradient), so commands never leave
  [-1, 1] (tunnel [-0.7, 0.7]).

Both turn a pod at most 90 deg from its current angle per call (reversing the
propeller instead), and :func:`throttle_for_slew` scales a pod's thrust while it is
still turning, so thrust is not pushed in the wrong direction.

Why not depend on ``skadipy`` (GPL-3.0; 0.0.3 is the release on PyPI): the licence
would bind this MIT package; it pulls in shapely, pyquaternion and qpsolvers[osqp];
and it is per-call numpy code on float32 state, which cannot run inside the compiled
low-level loop (:mod:`hil.sim.closed_loop`) that must do 18 000 steps in 0.18 s.

The math is in the ``@njit`` kernels of :mod:`hil.controllers.allocation_kernels`;
the classes here and the closed loop call the same ones. The thrust envelope is
:mod:`hil.controllers.envelope`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from hil.controllers.allocation_kernels import (
    extended_matrix,
    mma_allocate,
    pseudo_inverse_allocate,
)
from hil.controllers.errors import AllocationConfigError, NonFiniteDemandError
from hil.core.arrays import FloatArray, finite_vector
from hil.model.thrusters import VOYAGER_THRUSTERS, ThrusterParams

__all__ = [
    "AllocationResult",
    "Allocator",
    "MinimumMagnitudeAzimuthAllocator",
    "MmaArrays",
    "MmaConfig",
    "PseudoInverseAllocator",
    "null_space_basis",
    "weighted_pseudo_inverse",
]


@dataclass(frozen=True, slots=True)
class AllocationResult:
    """Output of one allocation.

    Attributes:
        commands: (tunnel, port, starboard), shape (3,), within the command limits.
        angles_rad: (port, starboard) azimuth angles, shape (2,) (rad, [-pi, pi)).
        achieved_n: B_e xi, the force (X, Y, N) these commands give at these angles
            (N, N, N m), shape (3,); equals the demand unless saturated.
        xi_n: The extended force vector, shape (5,) (N).
    """

    commands: FloatArray
    angles_rad: FloatArray
    achieved_n: FloatArray
    xi_n: FloatArray


class Allocator(Protocol):
    """Maps a generalized force demand to thruster commands and angles."""

    def allocate(self, tau_n: FloatArray, angles_rad: FloatArray | None = None) -> AllocationResult:
        """Allocate the demand ``tau_n`` = (X, Y, N), shape (3,) (N, N, N m).

        ``angles_rad`` are the pods' measured angles (2,), if known: the allocator
        turns no pod more than 90 deg from them; else from its last setpoint.
        """
        ...

    def reset(self) -> None:
        """Forget internal state (null-space parameter, last angles)."""
        ...


def _check_tau(tau_n: FloatArray) -> FloatArray:
    return finite_vector("force demand", tau_n, 3, AllocationConfigError, NonFiniteDemandError)


def _check_angles(angles_rad: FloatArray) -> FloatArray:
    return finite_vector("pod angles", angles_rad, 2, AllocationConfigError, NonFiniteDemandError)


def weighted_pseudo_inverse(be: FloatArray, weights: FloatArray) -> FloatArray:
    """Return B_w^+ = W^-1 B^T (B W^-1 B^T)^-1, shape (5, 3), for column weights (5,)."""
    w_inv = np.diag(1.0 / np.asarray(weights, dtype=np.float64))
    out: FloatArray = w_inv @ be.T @ np.linalg.inv(be @ w_inv @ be.T)
    return out


def null_space_basis(be: FloatArray) -> FloatArray:
    """Return an orthonormal basis of the null space of B_e, shape (5, 2)."""
    _, _, vt = np.linalg.svd(be)
    basis: FloatArray = np.ascontiguousarray(vt[3:].T)
    return basis


class PseudoInverseAllocator:
    """Plain Moore-Penrose allocation, each thruster clipped to its limit.

    Azimuths turn at most 90 deg per call (reversing thrust instead). Under
    saturation the clipped result is not the closest achievable force; use
    :class:`MinimumMagnitudeAzimuthAllocator` where that matters.
    """

    def __init__(self, params: ThrusterParams = VOYAGER_THRUSTERS) -> None:
        self.params = params
        self._tp = params.as_array()
        self._be = extended_matrix(self._tp)
        self._pinv = np.ascontiguousarray(np.linalg.pinv(self._be))
        self._hold = np.array([math.pi / 2, -math.pi / 2])

    def reset(self) -> None:
        """Return the held azimuth angles to the reference angles."""
        self._hold = np.array([math.pi / 2, -math.pi / 2])

    def allocate(self, tau_n: FloatArray, angles_rad: FloatArray | None = None) -> AllocationResult:
        """Allocate ``tau_n`` (X, Y, N), shape (3,), from pod angles ``angles_rad`` (2,).

        Raises:
            NonFiniteDemandError: If the demand or the angles hold NaN or inf.
        """
        tau = _check_tau(tau_n)
        hold = self._hold if angles_rad is None else _check_angles(angles_rad)
        u, alpha, xi = pseudo_inverse_allocate(self._tp, self._pinv, tau, hold)
        self._hold = alpha
        return AllocationResult(u, alpha, self._be @ xi, xi)


@dataclass(frozen=True, slots=True)
class MmaConfig:
    """Settings of :class:`MinimumMagnitudeAzimuthAllocator`.

    Attributes:
        gamma_nps: Steepest-descent gain on the null-space parameter (N/s). Ours: the
            lab's gamma = 0.01 acts on skadipy's internal filter state, not on newtons.
        lam: Weight of the pull toward the reference angles, in [0, 1): 0 is minimum
            magnitude only; near 1 pre-loads the azimuths against each other.
        eps_n: Smoothing of |f| near zero in the cost (N).
        dt_s: Allocation period (s); the lab runs at 20 Hz.
        iterations: Bounded least-squares iterations under saturation.
        reg: Tikhonov weight of the bounded least squares.
        reference_angles_rad: (port, starboard) reference angles (rad).
        column_weights: Weights of the pseudo-inverse, one per xi entry, (5,).
        cost_weights: Cost weights (tunnel, port, starboard).
        residual_weights: Weights on the (X, Y, N) residual when saturated.
    """

    gamma_nps: float = 1.0
    lam: float = 0.3
    eps_n: float = 0.02
    dt_s: float = 0.05
    iterations: int = 300
    reg: float = 1e-6
    reference_angles_rad: tuple[float, float] = (math.pi / 2, -math.pi / 2)
    column_weights: tuple[float, float, float, float, float] = (1.0, 1.0, 1.0, 1.0, 1.0)
    cost_weights: tuple[float, float, float] = (1.0, 1.0, 1.0)
    # N m weighted by 2 /m, about one over the thrusters' lever arms (0.39-0.46 m), so
    # a missed moment counts like the force that would make it; this also trades
    # sway for yaw-rate tracking under saturation (bench/lowlevel.py: yaw RMS -11 %).
    residual_weights: tuple[float, float, float] = (1.0, 1.0, 2.0)

    def __post_init__(self) -> None:
        scalars = (self.gamma_nps, self.lam, self.eps_n, self.dt_s, self.reg)
        vectors = (
            *self.reference_angles_rad,
            *self.column_weights,
            *self.cost_weights,
            *self.residual_weights,
        )
        if not all(math.isfinite(v) for v in (*scalars, *vectors)):
            raise AllocationConfigError(f"allocator settings must be finite, got {self!r}")
        if self.gamma_nps < 0.0 or self.eps_n <= 0.0 or self.dt_s <= 0.0 or self.reg < 0.0:
            raise AllocationConfigError(
                f"need gamma >= 0, eps > 0, dt > 0, reg >= 0, got {self.gamma_nps!r}, "
                f"{self.eps_n!r}, {self.dt_s!r}, {self.reg!r}"
            )
        if not 0.0 <= self.lam < 1.0:
            raise AllocationConfigError(f"lam must be in [0, 1), got {self.lam!r}")
        if self.iterations < 1:
            raise AllocationConfigError(f"iterations must be >= 1, got {self.iterations!r}")
        if min(self.column_weights) <= 0.0 or min(self.residual_weights) <= 0.0:
            raise AllocationConfigError(
                f"column and residual weights must be positive, got {self.column_weights!r}, "
                f"{self.residual_weights!r}"
            )

    def cfg_array(self) -> FloatArray:
        """Return (gamma, lam, eps, dt, iterations, reg), the kernel's ``cfg`` (6,)."""
        return np.array(
            [self.gamma_nps, self.lam, self.eps_n, self.dt_s, float(self.iterations), self.reg]
        )

    def reference_directions(self) -> FloatArray:
        """Return the unit thrust directions at the reference angles, shape (2, 2)."""
        a = np.asarray(self.reference_angles_rad)
        return np.ascontiguousarray(np.stack([np.cos(a), np.sin(a)], axis=1))


@dataclass(frozen=True)
class MmaArrays:
    """The constant arrays :func:`mma_allocate` reads (built once per configuration).

    Attributes:
        tp: Thruster parameter array.
        be: B_e, shape (3, 5).
        b_pinv: Weighted pseudo-inverse, shape (5, 3).
        q: Null-space basis, shape (5, 2).
        cfg: Scalar settings, shape (6,).
        a_ref: Reference directions, shape (2, 2).
        weights: Cost weights, shape (3,).
        wq: Residual weights, shape (3,).
    """

    tp: FloatArray
    be: FloatArray
    b_pinv: FloatArray
    q: FloatArray
    cfg: FloatArray
    a_ref: FloatArray
    weights: FloatArray
    wq: FloatArray

    @staticmethod
    def build(params: ThrusterParams, config: MmaConfig) -> MmaArrays:
        """Return the arrays for ``params`` and ``config``."""
        tp = params.as_array()
        be = extended_matrix(tp)
        return MmaArrays(
            tp=tp,
            be=be,
            b_pinv=np.ascontiguousarray(
                weighted_pseudo_inverse(be, np.asarray(config.column_weights))
            ),
            q=null_space_basis(be),
            cfg=config.cfg_array(),
            a_ref=config.reference_directions(),
            weights=np.asarray(config.cost_weights, dtype=np.float64),
            wq=np.asarray(config.residual_weights, dtype=np.float64),
        )


class MinimumMagnitudeAzimuthAllocator:
    """Weighted pseudo-inverse plus a null-space term (magnitude and azimuth), bounded.

    Stateful: the null-space parameter theta evolves by one gradient step per call,
    so call it at the rate ``config.dt_s`` describes.
    """

    def __init__(
        self, params: ThrusterParams = VOYAGER_THRUSTERS, config: MmaConfig | None = None
    ) -> None:
        self.params = params
        self.config = MmaConfig() if config is None else config
        self.arrays = MmaArrays.build(params, self.config)
        self._theta = np.zeros(2)
        self._hold = np.asarray(self.config.reference_angles_rad, dtype=np.float64)

    @property
    def theta(self) -> FloatArray:
        """Return a copy of the null-space parameter, shape (2,) (N)."""
        return self._theta.copy()

    def reset(self) -> None:
        """Zero the null-space parameter and return the held angles to the references."""
        self._theta = np.zeros(2)
        self._hold = np.asarray(self.config.reference_angles_rad, dtype=np.float64)

    def allocate(self, tau_n: FloatArray, angles_rad: FloatArray | None = None) -> AllocationResult:
        """Allocate ``tau_n`` (X, Y, N), shape (3,), from pod angles ``angles_rad`` (2,).

        Raises:
            NonFiniteDemandError: If the demand or the angles hold NaN or inf.
        """
        tau = _check_tau(tau_n)
        hold = self._hold if angles_rad is None else _check_angles(angles_rad)
        a = self.arrays
        u, alpha, xi, theta = mma_allocate(
            a.tp, a.be, a.b_pinv, a.q, self._theta, tau, hold, a.cfg, a.a_ref,
            a.weights, a.wq,
        )  # fmt: skip
        self._theta = theta
        self._hold = alpha
        return AllocationResult(u, alpha, a.be @ xi, xi)
