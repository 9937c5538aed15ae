"""The transient budget: how far the real closed loop may stray from the exact arc in one period.

The symbolic abstraction plans with exact arcs: over a command period the vessel is
assumed to fly the reference u = (u_lin, u_r) = (u, v, r) exactly. Let the period start
at t = 0 at the true pose (p0, psi0) with u held. The exact arc is
``psibar(t) = psi0 + u_r t`` and ``pbar(t) = p0 + int_0^t R(psibar(s)) u_lin ds``, R the
planar rotation. The low level only tracks u, worst right after the reference changes,
so the true pose (p(t), psi(t)) strays from the arc. A :class:`TransientBudget` bounds
that deviation directly, as a function of the time since the period began in bins of
``bin_s``, for three classes of period (:class:`BudgetClass`): *hold* (the reference
equals the previous period's), *change* (it moved by one input-grid step on some axes)
and *start* (the first :data:`START_PERIODS` periods of a run, from rest or already
moving):

- :attr:`TransientBudget.position_m` ``[c, j]`` bounds ``|p(t) - pbar(t)|`` (m) and
  :attr:`TransientBudget.heading_rad` ``[c, j]`` bounds ``|psi(t) - psibar(t)|`` (rad)
  for every t up to the end of bin j, ``(j + 1) bin_s`` (running maxima: non-decreasing
  in j); :meth:`TransientBudget.position_bound_m` and
  :meth:`TransientBudget.heading_bound_rad` look them up.
- The bins cover the period ``tau`` plus :data:`LATE_S`: a command may be held up to two
  20-Hz ticks late, and the deviation grows for as long as the reference is held.
  Asking past the horizon is an error, never an extrapolation.

The numbers are measured on the code the vessel runs (:mod:`hil.sim.transient`: the
compiled closed loop on references that obey the game's one-step rule, periods of
random length in [tau, tau + LATE_S]) and shipped in each scenario's ``[transient]``.
Measuring the deviation itself, rather than integrating velocity-error envelopes into
position and heading bounds (``int hypot(env_u, env_v) + |u_lin| int theta``), matters:
the per-bin maxima of the envelopes come from different runs and axes and never occur
together, and that integral was 4-8 times the largest deviation measured.

The velocity envelopes (:attr:`TransientBudget.envelopes`, max ``|nu - nu_ref|`` per
class, bin and axis) are kept beside them, for checks of the tracking itself. The
estimation bounds (:attr:`TransientBudget.estimation_position_m`,
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
from numpy.typing import ArrayLike

from hil.core.arrays import FloatArray, IntArray

__all__ = [
    "LATE_S",
    "N_CLASSES",
    "PERIOD_BINS",
    "START_PERIODS",
    "BudgetClass",
    "TransientBudget",
    "TransientBudgetError",
    "horizon_bins",
]

N_CLASSES = 3
"""Number of budget classes (the first axis of every table of a :class:`TransientBudget`)."""

LATE_S = 0.1
"""How much longer than ``tau`` a period may last (s): a command held two 20-Hz ticks late."""

START_PERIODS = 2
"""Periods a start counts as (class START): a vessel started moving, with its thrusters
idle, is still settling through the period after the first, and counting that one as a
hold would set the hold bound (measured: 0.053 m against 0.023 m for holds elsewhere).
The runtime takes its first this many decisions as first decisions."""

PERIOD_BINS = 8
"""Bins per command period of :meth:`TransientBudget.zero` (0.25 s for tau = 2 s)."""

_CLASS_NAMES = ("hold", "change", "start")
_TOL = 1e-9


class BudgetClass(IntEnum):
    """Which bounds apply to a command period (the index into the tables' first axis)."""

    HOLD = 0
    """The reference equals the previous period's."""
    CHANGE = 1
    """The reference moved by at most one input-grid step per axis, at least one axis."""
    START = 2
    """The first :data:`START_PERIODS` periods of a run: from rest, or moving near an
    input p*, any u in N(p*), then one-step changes or holds."""


class TransientBudgetError(ValueError):
    """A transient budget, or a question to one, that cannot be used; the message says why."""


def horizon_bins(tau_s: float, bin_s: float) -> int:
    """Return the fewest bins of `bin_s` that cover a period held late, tau_s + LATE_S.

    Raises:
        TransientBudgetError: `tau_s` or `bin_s` is not finite and positive.
    """
    if not (math.isfinite(tau_s) and tau_s > 0.0 and math.isfinite(bin_s) and bin_s > 0.0):
        raise TransientBudgetError(
            f"need tau_s > 0 and bin_s > 0, got tau_s={tau_s!r}, bin_s={bin_s!r}"
        )
    return max(1, math.ceil((tau_s + LATE_S) / bin_s - _TOL))


@dataclass(frozen=True, slots=True, eq=False)
class TransientBudget:
    """Time-resolved bounds on the deviation from the exact arc per period class.

    Equality and hashing compare the numbers and the source (the tables are arrays);
    ``repr`` names the numbers by :meth:`digest`, so a scenario's hash covers them.

    Attributes:
        bin_s: Width of each time bin (s), > 0.
        envelopes: Shape (3, n_bins, 3), indexed [class (:class:`BudgetClass`), bin,
            axis (surge m/s, sway m/s, yaw rate rad/s)]: a bound on |nu - nu_ref| over
            t in [j bin_s, (j + 1) bin_s] of the period, t = 0 when the reference is
            issued.
        position_m: Shape (3, n_bins) [class, bin]: a bound on |p(t) - pbar(t)| (m) for
            every t in [0, (j + 1) bin_s], non-decreasing in j.
        heading_rad: Shape (3, n_bins) [class, bin]: the same for |psi(t) - psibar(t)|
            (rad).
        estimation_position_m: Bound on |(x_hat, y_hat) - (x, y)| of the EKF (m).
        estimation_heading_rad: Bound on |psi_hat - psi| of the EKF (rad).
        source: How the numbers were obtained (for people).

    Every table is finite, >= 0 and stored read-only (copied).

    Raises:
        TransientBudgetError: A number is not finite or negative, a table has another
            shape, or a deviation bound decreases from one bin to the next.
    """

    bin_s: float
    envelopes: FloatArray
    position_m: FloatArray
    heading_rad: FloatArray
    estimation_position_m: float
    estimation_heading_rad: float
    source: str = ""

    def __post_init__(self) -> None:
        bin_s = _real("bin_s", self.bin_s)
        if not bin_s > 0.0:
            raise TransientBudgetError(f"bin_s must be > 0 (s), got {self.bin_s!r}")
        object.__setattr__(self, "bin_s", bin_s)
        env = _table("envelopes", self.envelopes)
        if env.ndim != 3 or env.shape[0] != N_CLASSES or env.shape[1] < 1 or env.shape[2] != 3:
            raise TransientBudgetError(
                f"envelopes must have shape ({N_CLASSES}, n_bins >= 1, 3) [class, bin, axis], "
                f"got {env.shape!r}"
            )
        _nonnegative("envelopes", env, ("class", "bin", "axis"))
        object.__setattr__(self, "envelopes", env)
        n_bins = env.shape[1]
        for name in ("position_m", "heading_rad"):
            arr = _table(name, getattr(self, name))
            if arr.shape != (N_CLASSES, n_bins):
                raise TransientBudgetError(
                    f"{name} must have shape ({N_CLASSES}, {n_bins}) [class, bin] like the "
                    f"envelopes, got {arr.shape!r}"
                )
            _nonnegative(name, arr, ("class", "bin"))
            drops = np.argwhere(np.diff(arr, axis=1) < 0.0)
            if drops.size:
                cls, j = (int(i) for i in drops[0])
                raise TransientBudgetError(
                    f"{name} must be non-decreasing over the bins (a bound up to each bin's "
                    f"end), got {arr[cls, j]!r} then {arr[cls, j + 1]!r} at "
                    f"[class {cls} ({_CLASS_NAMES[cls]}), bins {j}-{j + 1}]"
                )
            object.__setattr__(self, name, arr)
        for name in ("estimation_position_m", "estimation_heading_rad"):
            value = _real(name, getattr(self, name))
            if value < 0.0:
                raise TransientBudgetError(f"{name} must be >= 0, got {value!r}")
            object.__setattr__(self, name, value)
        if not isinstance(self.source, str):
            raise TransientBudgetError(f"source must be a string, got {self.source!r}")

    @staticmethod
    def zero(tau_s: float, n_bins: int | None = None) -> TransientBudget:
        """Return the paper's ideal budget: every bound zero.

        Args:
            tau_s: Command period (s), > 0; the bins are ``tau_s / PERIOD_BINS`` wide.
            n_bins: Number of bins; default (and least) the fewest that cover
                ``tau_s + LATE_S`` (9 for tau = 2 s).

        Raises:
            TransientBudgetError: `tau_s` is not positive, or `n_bins` too few.
        """
        if not (math.isfinite(tau_s) and tau_s > 0.0):
            raise TransientBudgetError(f"need tau_s > 0, got tau_s={tau_s!r}")
        bin_s = tau_s / PERIOD_BINS
        need = horizon_bins(tau_s, bin_s)
        n = need if n_bins is None else n_bins
        if n < need:
            raise TransientBudgetError(
                f"n_bins={n_bins!r} bins of {bin_s!r} s do not cover tau_s + LATE_S = "
                f"{tau_s + LATE_S!r} s (need {need})"
            )
        return TransientBudget(
            bin_s=bin_s,
            envelopes=np.zeros((N_CLASSES, n, 3)),
            position_m=np.zeros((N_CLASSES, n)),
            heading_rad=np.zeros((N_CLASSES, n)),
            estimation_position_m=0.0,
            estimation_heading_rad=0.0,
            source="zero: the paper's exact tracking (no [transient] table)",
        )

    @property
    def n_bins(self) -> int:
        """Return the number of time bins."""
        return int(self.envelopes.shape[1])

    @property
    def n_classes(self) -> int:
        """Return the number of period classes (3: hold, change, start)."""
        return int(self.envelopes.shape[0])

    def horizon_s(self) -> float:
        """Return the time the bins cover, n_bins * bin_s (s)."""
        return self.n_bins * self.bin_s

    def is_zero(self) -> bool:
        """Return whether every bound is zero."""
        return bool(
            not np.any(self.envelopes)
            and not np.any(self.position_m)
            and not np.any(self.heading_rad)
            and self.estimation_position_m == 0.0
            and self.estimation_heading_rad == 0.0
        )

    def bin_index(self, t_s: ArrayLike) -> IntArray:
        """Return the bin whose bound covers each time: j with t in (j bin_s, (j + 1) bin_s].

        t = 0 is in bin 0; a time on a bin's end is in that bin (the tighter bound).

        Args:
            t_s: Times since the period began (s), shape (T,), finite, in
                [0, :meth:`horizon_s`].

        Returns:
            Shape (T,).

        Raises:
            TransientBudgetError: Times of another shape, negative, not finite, or past
                the horizon.
        """
        t = _times(t_s)
        horizon = self.horizon_s()
        late = t > horizon + _TOL * max(1.0, horizon)
        if np.any(late):
            raise TransientBudgetError(
                f"t_s = {float(t[late][0])!r} s is past the budget's horizon "
                f"{self.n_bins} x {self.bin_s!r} = {horizon!r} s: it was measured over periods "
                f"of tau to tau + {LATE_S!r} s only"
            )
        j = np.ceil(t / self.bin_s - _TOL).astype(np.int64) - 1
        out: IntArray = np.clip(j, 0, self.n_bins - 1)
        return out

    def heading_bound_rad(self, cls: int, t_s: ArrayLike) -> FloatArray:
        """Return the bound on |psi(s) - psibar(s)| for all s <= t (rad).

        Args:
            cls: Budget class (:class:`BudgetClass`: 0 hold, 1 change, 2 start).
            t_s: Times since the period began (s), shape (T,), finite, in
                [0, :meth:`horizon_s`].

        Returns:
            Shape (T,) (rad): ``heading_rad[cls, bin(t)]``.

        Raises:
            TransientBudgetError: Unknown class, or times of another shape, negative, not
                finite or past the horizon.
        """
        row = self.heading_rad[_class(cls)]
        out: FloatArray = row[self.bin_index(t_s)]
        return out

    def position_bound_m(self, cls: int, speed_mps: ArrayLike, t_s: ArrayLike) -> FloatArray:
        """Return the bound on |p(s) - pbar(s)| for all s <= t, for each reference speed (m).

        The bound was measured on every input of the grid, so it does not depend on the
        speed; the speeds only shape the answer.

        Args:
            cls: Budget class (:class:`BudgetClass`: 0 hold, 1 change, 2 start).
            speed_mps: Reference speeds |u_lin| = hypot(u, v) (m/s), shape (m,), >= 0.
            t_s: Times since the period began (s), shape (T,), finite, in
                [0, :meth:`horizon_s`].

        Returns:
            Shape (m, T) (m), indexed [speed, time]: ``position_m[cls, bin(t)]``.

        Raises:
            TransientBudgetError: Unknown class, or speeds or times of another shape,
                negative, not finite, or times past the horizon.
        """
        row = self.position_m[_class(cls)]
        speed = _nonnegative_vector("speed_mps", speed_mps)
        bound = row[self.bin_index(t_s)]
        out: FloatArray = np.broadcast_to(bound[None, :], (speed.shape[0], bound.shape[0])).copy()
        return out

    def digest(self) -> str:
        """Return a stable 16-hex-digit hash of the numbers (bins, every table, estimation).

        The source text is left out: two budgets with the same numbers give the same
        tables. Independent of the machine's byte order.
        """
        h = hashlib.sha256(b"hil.core.transient/2")
        h.update(struct.pack("<d", self.bin_s))
        h.update(struct.pack("<3q", *self.envelopes.shape))
        for arr in (self.envelopes, self.position_m, self.heading_rad):
            h.update(np.ascontiguousarray(arr, dtype="<f8").tobytes())
        h.update(struct.pack("<2d", self.estimation_position_m, self.estimation_heading_rad))
        return h.hexdigest()[:16]

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, TransientBudget):
            return NotImplemented
        return (
            self.bin_s == other.bin_s
            and self.envelopes.shape == other.envelopes.shape
            and bool(np.array_equal(self.envelopes, other.envelopes))
            and bool(np.array_equal(self.position_m, other.position_m))
            and bool(np.array_equal(self.heading_rad, other.heading_rad))
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


def _table(name: str, value: object) -> FloatArray:
    try:
        arr = np.array(value, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as err:
        raise TransientBudgetError(f"{name} must be an array of numbers: {err}") from err
    arr.setflags(write=False)
    return arr


def _nonnegative(name: str, arr: FloatArray, axes: tuple[str, ...]) -> None:
    if not np.all(np.isfinite(arr)):
        raise TransientBudgetError(f"{name} must be finite")
    if np.any(arr < 0.0):
        where = tuple(int(i) for i in np.argwhere(arr < 0.0)[0])
        at = ", ".join(f"{a} {i}" for a, i in zip(axes, where, strict=True))
        raise TransientBudgetError(f"{name} must be >= 0, got {arr[where]!r} at [{at}]")


def _class(cls: int) -> int:
    if isinstance(cls, bool) or not isinstance(cls, int | np.integer) or not 0 <= cls < N_CLASSES:
        raise TransientBudgetError(f"class must be 0 (hold), 1 (change) or 2 (start), got {cls!r}")
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
