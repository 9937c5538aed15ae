"""The transient budget: how far the real closed loop may stray from the exact arc in one period.

The symbolic abstraction plans with exact arcs: over a command period the vessel is
assumed to fly the reference u = (u_lin, u_r) = (u, v, r) exactly. The low level only
tracks it, and worst right after the reference changes. A :class:`TransientBudget`
bounds the true velocity error ``|nu - nu_ref|`` per axis (surge m/s, sway m/s, yaw
rate rad/s) as a function of the time since the period began, in bins of ``bin_s``,
for two classes of period (:class:`BudgetClass`): *hold* (the reference equals the
previous period's) and *change* (it moved by one input-grid step on some axes, or the
period is the first of a run that started moving). From the envelopes it returns how
far the true heading and position can be from the exact arc started at the true pose
at the period's start (:meth:`TransientBudget.heading_bound_rad`,
:meth:`TransientBudget.position_bound_m`). The numbers are measured on the code the
vessel runs (:mod:`hil.sim.transient`) and shipped in each scenario's ``[transient]``.

Why the bound holds. Let the period start at t = 0 at the true pose (p0, psi0) with the
reference u held. The exact arc is ``psibar(t) = psi0 + u_r t`` and
``pbar(t) = p0 + int_0^t R(psibar(s)) u_lin ds``; the vessel flies
``psi(t) = psi0 + int_0^t r ds`` and ``p(t) = p0 + int_0^t R(psi(s)) nu_lin(s) ds``,
with R the planar rotation and nu_lin = (u, v). Then

- ``psi(t) - psibar(t) = int_0^t (r - u_r) ds``, so
  ``|psi(t) - psibar(t)| <= int_0^t env_r(s) ds = theta(t)``;
- ``p(t) - pbar(t) = int_0^t R(psi)(nu_lin - u_lin) ds
  + int_0^t (R(psi) - R(psibar)) u_lin ds``. A rotation keeps lengths, so the first
  integrand is at most ``hypot(env_u, env_v)``; and ``||R(a) - R(b)|| =
  2 |sin((a - b) / 2)| <= |a - b|``, so the second is at most ``|u_lin| theta(s)``.
  Hence ``|p(t) - pbar(t)| <= int_0^t hypot(env_u, env_v) ds + |u_lin| int_0^t
  theta(s) ds = rho(t)``.

The envelopes are piecewise constant over the bins, so theta is piecewise linear and
rho piecewise quadratic; both are evaluated exactly here. Past the last bin the last
bin's envelope is extended (a late tick that holds a reference longer than the period).
The estimation bounds (:attr:`TransientBudget.estimation_position_m`,
:attr:`TransientBudget.estimation_heading_rad`) are separate: they bound how far the
EKF's pose, on which decisions are taken, is from the true pose, and add to the cell a
decision is taken in, not to the arc.
"""

from __future__ import annotations

import hashlib
import math
import struct
from dataclasses import dataclass
from enum import IntEnum

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

__all__ = ["N_CLASSES", "BudgetClass", "TransientBudget", "TransientBudgetError"]

N_CLASSES = 2
"""Number of budget classes (the first axis of :attr:`TransientBudget.envelopes`)."""


class BudgetClass(IntEnum):
    """Which envelope budgets a command period (the index into the envelopes' first axis)."""

    HOLD = 0
    """The reference equals the previous period's."""
    CHANGE = 1
    """The reference moved (one grid step per axis at most), or a moving run's first period."""


class TransientBudgetError(ValueError):
    """A transient budget, or a question to one, that cannot be used; the message says why."""


@dataclass(frozen=True, slots=True, eq=False)
class TransientBudget:
    """Time-resolved bounds on the velocity error per period class, and the EKF's pose error.

    Equality and hashing compare the numbers and the source (the envelopes are arrays);
    ``repr`` names the numbers by :meth:`digest`, so a scenario's hash covers them.

    Attributes:
        bin_s: Width of each time bin (s), > 0.
        envelopes: Shape (2, n_bins, 3), indexed [class (0 hold, 1 change), bin, axis
            (surge m/s, sway m/s, yaw rate rad/s)]: a bound on |nu - nu_ref| over
            t in [j bin_s, (j + 1) bin_s] of the period, t = 0 when the reference is
            issued. Finite, >= 0; stored read-only.
        estimation_position_m: Bound on |(x_hat, y_hat) - (x, y)| of the EKF (m).
        estimation_heading_rad: Bound on |psi_hat - psi| of the EKF (rad).
        source: How the numbers were obtained (for people).

    Raises:
        TransientBudgetError: A number is not finite or negative, or the envelopes have
            another shape.
    """

    bin_s: float
    envelopes: FloatArray
    estimation_position_m: float
    estimation_heading_rad: float
    source: str = ""

    def __post_init__(self) -> None:
        bin_s = _real("bin_s", self.bin_s)
        if not bin_s > 0.0:
            raise TransientBudgetError(f"bin_s must be > 0 (s), got {self.bin_s!r}")
        env = np.array(self.envelopes, dtype=np.float64, copy=True)
        if env.ndim != 3 or env.shape[0] != N_CLASSES or env.shape[1] < 1 or env.shape[2] != 3:
            raise TransientBudgetError(
                f"envelopes must have shape (2, n_bins >= 1, 3) [class, bin, axis], "
                f"got {env.shape!r}"
            )
        if not np.all(np.isfinite(env)):
            raise TransientBudgetError("envelopes must be finite")
        if np.any(env < 0.0):
            cls, j, axis = (int(i) for i in np.argwhere(env < 0.0)[0])
            raise TransientBudgetError(
                f"envelopes must be >= 0, got {env[cls, j, axis]!r} at "
                f"[class {cls}, bin {j}, axis {axis}]"
            )
        env.setflags(write=False)
        object.__setattr__(self, "bin_s", bin_s)
        object.__setattr__(self, "envelopes", env)
        for name in ("estimation_position_m", "estimation_heading_rad"):
            value = _real(name, getattr(self, name))
            if value < 0.0:
                raise TransientBudgetError(f"{name} must be >= 0, got {value!r}")
            object.__setattr__(self, name, value)
        if not isinstance(self.source, str):
            raise TransientBudgetError(f"source must be a string, got {self.source!r}")

    @staticmethod
    def zero(tau_s: float, n_bins: int = 8) -> TransientBudget:
        """Return the paper's ideal budget: every envelope and estimation bound zero.

        Args:
            tau_s: Command period (s) the bins cover, > 0.
            n_bins: Number of bins, >= 1.

        Raises:
            TransientBudgetError: `tau_s` is not positive or `n_bins` < 1.
        """
        if not (math.isfinite(tau_s) and tau_s > 0.0) or n_bins < 1:
            raise TransientBudgetError(
                f"need tau_s > 0 and n_bins >= 1, got tau_s={tau_s!r}, n_bins={n_bins!r}"
            )
        return TransientBudget(
            bin_s=tau_s / n_bins,
            envelopes=np.zeros((N_CLASSES, n_bins, 3)),
            estimation_position_m=0.0,
            estimation_heading_rad=0.0,
            source="zero: the paper's exact tracking (no [transient] table)",
        )

    @property
    def n_bins(self) -> int:
        """Return the number of time bins."""
        return int(self.envelopes.shape[1])

    def horizon_s(self) -> float:
        """Return the time the bins cover, n_bins * bin_s (s)."""
        return self.n_bins * self.bin_s

    def is_zero(self) -> bool:
        """Return whether every envelope and estimation bound is zero."""
        return bool(
            not np.any(self.envelopes)
            and self.estimation_position_m == 0.0
            and self.estimation_heading_rad == 0.0
        )

    def heading_bound_rad(self, cls: int, t_s: ArrayLike) -> FloatArray:
        """Return theta(t) = int_0^t env_r(s) ds, the bound on |psi - psibar| (rad).

        Args:
            cls: Budget class (:class:`BudgetClass`: 0 hold, 1 change).
            t_s: Times since the period began (s), shape (T,), finite, >= 0; past the
                horizon the last bin's envelope is extended.

        Returns:
            Shape (T,) (rad).

        Raises:
            TransientBudgetError: Unknown class, or times of another shape, negative or
                not finite.
        """
        env = self.envelopes[_class(cls)]
        t = _times(t_s)
        j, dt = self._bin_of(t)
        theta = _cumulative(env[:, 2], self.bin_s)
        out: FloatArray = theta[j] + env[j, 2] * dt
        return out

    def position_bound_m(self, cls: int, speed_mps: ArrayLike, t_s: ArrayLike) -> FloatArray:
        """Return rho(t), the bound on |p - pbar| for each reference speed (m).

        ``rho(t) = int_0^t hypot(env_u, env_v) ds + speed * int_0^t theta(s) ds``, exact
        for the piecewise-constant envelopes (piecewise linear plus quadratic).

        Args:
            cls: Budget class (:class:`BudgetClass`: 0 hold, 1 change).
            speed_mps: Reference speeds |u_lin| = hypot(u, v) (m/s), shape (m,), >= 0.
            t_s: Times since the period began (s), shape (T,), finite, >= 0.

        Returns:
            Shape (m, T) (m), indexed [speed, time].

        Raises:
            TransientBudgetError: Unknown class, or speeds or times of another shape,
                negative or not finite.
        """
        env = self.envelopes[_class(cls)]
        speed = _nonnegative_vector("speed_mps", speed_mps)
        t = _times(t_s)
        j, dt = self._bin_of(t)
        lin = np.hypot(env[:, 0], env[:, 1])
        env_r = env[:, 2]
        theta = _cumulative(env_r, self.bin_s)  # (n + 1,) at the bin edges
        lin_int = _cumulative(lin, self.bin_s)
        # int of theta over bin k: theta_k bin + env_r[k] bin^2 / 2
        theta_int = np.concatenate(
            ([0.0], np.cumsum(theta[:-1] * self.bin_s + 0.5 * env_r * self.bin_s**2))
        )
        drift = lin_int[j] + lin[j] * dt
        swing = theta_int[j] + theta[j] * dt + 0.5 * env_r[j] * dt * dt
        out: FloatArray = drift[None, :] + speed[:, None] * swing[None, :]
        return out

    def digest(self) -> str:
        """Return a stable 16-hex-digit hash of the numbers (bins, envelopes, estimation).

        The source text is left out: two budgets with the same numbers give the same
        tables. Independent of the machine's byte order.
        """
        h = hashlib.sha256(b"hil.core.transient/1")
        h.update(struct.pack("<d", self.bin_s))
        h.update(struct.pack("<3q", *self.envelopes.shape))
        h.update(np.ascontiguousarray(self.envelopes, dtype="<f8").tobytes())
        h.update(struct.pack("<2d", self.estimation_position_m, self.estimation_heading_rad))
        return h.hexdigest()[:16]

    def _bin_of(self, t: FloatArray) -> tuple[IntArray, FloatArray]:
        """Return the bin of each time (the last past the horizon) and the time into it."""
        j = np.minimum(np.floor(t / self.bin_s), self.n_bins - 1).astype(np.int64)
        return j, t - j * self.bin_s

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, TransientBudget):
            return NotImplemented
        return (
            self.bin_s == other.bin_s
            and self.envelopes.shape == other.envelopes.shape
            and bool(np.array_equal(self.envelopes, other.envelopes))
            and self.estimation_position_m == other.estimation_position_m
            and self.estimation_heading_rad == other.estimation_heading_rad
            and self.source == other.source
        )

    def __hash__(self) -> int:
        return hash((self.digest(), self.source))

    def __repr__(self) -> str:
        return (
            f"TransientBudget(bin_s={self.bin_s!r}, n_bins={self.n_bins}, "
            f"digest={self.digest()!r}, estimation_position_m={self.estimation_position_m!r}, "
            f"estimation_heading_rad={self.estimation_heading_rad!r}, source={self.source!r})"
        )


def _real(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise TransientBudgetError(f"{name} must be a number, got {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise TransientBudgetError(f"{name} must be finite, got {value!r}")
    return out


def _class(cls: int) -> int:
    if isinstance(cls, bool) or not isinstance(cls, int | np.integer) or not 0 <= cls < N_CLASSES:
        raise TransientBudgetError(f"class must be 0 (hold) or 1 (change), got {cls!r}")
    return int(cls)


def _times(t_s: ArrayLike) -> FloatArray:
    t = np.asarray(t_s, dtype=np.float64)
    if t.ndim != 1:
        raise TransientBudgetError(f"t_s must have shape (T,), got {t.shape!r}")
    if not np.all(np.isfinite(t)) or np.any(t < 0.0):
        raise TransientBudgetError("t_s must be finite and >= 0 (s since the period began)")
    return t


def _nonnegative_vector(name: str, values: ArrayLike) -> FloatArray:
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 1:
        raise TransientBudgetError(f"{name} must have shape (m,), got {v.shape!r}")
    if not np.all(np.isfinite(v)) or np.any(v < 0.0):
        raise TransientBudgetError(f"{name} must be finite and >= 0")
    return v


def _cumulative(rate: FloatArray, bin_s: float) -> FloatArray:
    """Return the integral of a piecewise-constant `rate` (n,) at the n + 1 bin edges."""
    out: FloatArray = np.concatenate(([0.0], np.cumsum(rate * bin_s)))
    return out
