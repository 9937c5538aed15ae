"""The EKF's consistency watch: is the estimation premise still true on this run?

The guarantee assumes the estimate is within the estimation bound of the true pose
(the budget's ``estimation_position_m``, measured with the filter's noise model). That
premise cannot be checked against the truth on the vessel, but its symptoms can, on
every pose the filter judges (its innovation y against the prior, S = P[:3, :3] + R):

- the normalized innovation squared (NIS) y^T S^-1 y of a consistent filter is
  chi-square with 3 degrees of freedom, so the mean over n poses is chi2(3 n) / n; a
  window's mean above its 1 - :data:`NIS_ALPHA` quantile says S understates the real
  innovations (noisier poses than the model, a wrong prediction);
- the gate (``gate_pose_chi2``, 99.9 %) refuses about 0.1 % of a consistent filter's
  poses; a window refusing more than :attr:`ConsistencyLimits.max_gated_fraction`;
- with the estimate within b of the truth and pose noise sigma per axis,
  E|y_pos|^2 <= 2 sigma^2 + b^2; a window whose root mean square position innovation
  is above sqrt(2 sigma^2 + b^2) says the estimate is farther off than the bound, or
  the poses noisier than the model the bound was measured with.

Each is judged over the last :attr:`ConsistencyLimits.window` poses (1 s at 100 Hz),
once at least :attr:`ConsistencyLimits.min_poses` are in, so a single outlier does not
count and a sustained breach does. The first breach is reported once
(:class:`ConsistencyBreach`); the runtime's reaction is a safe stop.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

__all__ = ["NIS_ALPHA", "ConsistencyBreach", "ConsistencyLimits", "ConsistencyWatch", "nis_bound"]

NIS_ALPHA = 1e-6
"""Chance that a consistent filter's window mean exceeds :func:`nis_bound`. Small
because the window slides: over a 10-min run about 600 nearly independent windows are
judged, so a consistent filter breaches with a chance below 1e-3 per run."""

_Z_ALPHA = 4.753
"""The standard normal's 1 - NIS_ALPHA quantile."""

_POSE_DOF = 3


def nis_bound(n: int) -> float:
    """Return the 1 - :data:`NIS_ALPHA` quantile of the mean NIS of n poses (chi2(3 n) / n).

    Wilson-Hilferty's approximation of the chi-square quantile (within 0.2 % of the
    exact one for n >= 50, the windows judged; no scipy import on the vessel).
    """
    k = _POSE_DOF * max(int(n), 1)
    c = 2.0 / (9.0 * k)
    return k * (1.0 - c + _Z_ALPHA * math.sqrt(c)) ** 3 / max(int(n), 1)


@dataclass(frozen=True, slots=True)
class ConsistencyLimits:
    """What the watch judges against.

    Attributes:
        estimation_position_m: The estimation bound the guarantee assumes (m), >= 0.
        pose_std_m: The filter's pose noise per axis (m), > 0
            (``ObserverConfig.pose_std_m``).
        window: Poses per window (>= 2; 100: 1 s at 100 Hz).
        min_poses: Poses a window needs before it is judged (2..window).
        max_gated_fraction: Largest share of a window's poses the gate may refuse.
    """

    estimation_position_m: float
    pose_std_m: float
    window: int = 100
    min_poses: int = 50
    max_gated_fraction: float = 0.05

    def __post_init__(self) -> None:
        if not (self.estimation_position_m >= 0.0 and self.pose_std_m > 0.0):
            raise ValueError(
                "estimation_position_m must be >= 0 and pose_std_m > 0, got "
                f"{self.estimation_position_m!r} and {self.pose_std_m!r}"
            )
        if not 2 <= self.min_poses <= self.window:
            raise ValueError(f"need 2 <= min_poses <= window, got {self.min_poses}, {self.window}")
        if not 0.0 < self.max_gated_fraction < 1.0:
            raise ValueError(
                f"max_gated_fraction must be in (0, 1), got {self.max_gated_fraction!r}"
            )

    @property
    def innovation_bound_m(self) -> float:
        """Return sqrt(2 sigma^2 + b^2): the largest RMS position innovation (m)."""
        return math.sqrt(2.0 * self.pose_std_m**2 + self.estimation_position_m**2)


@dataclass(frozen=True, slots=True)
class ConsistencyBreach:
    """A window in which the filter was not consistent with its noise model.

    Attributes:
        t_ns: Stamp of the pose that completed the window (ns).
        poses: Poses in the window.
        mean_nis: The window's mean NIS; nis_bound its limit.
        gated_fraction: Share of the window's poses the gate refused;
            max_gated_fraction its limit.
        rms_innovation_m: Root mean square position innovation (m);
            innovation_bound_m its limit.
    """

    t_ns: int
    poses: int
    mean_nis: float
    nis_bound: float
    gated_fraction: float
    max_gated_fraction: float
    rms_innovation_m: float
    innovation_bound_m: float

    @property
    def broken(self) -> tuple[str, ...]:
        """Return the names of the figures over their limits."""
        out = []
        if not self.mean_nis <= self.nis_bound:
            out.append("NIS")
        if self.gated_fraction > self.max_gated_fraction:
            out.append("gated poses")
        if not self.rms_innovation_m <= self.innovation_bound_m:
            out.append("innovation")
        return tuple(out)

    def text(self) -> str:
        """Return the breach in words, with every figure and its limit."""
        return (
            f"estimation premise broken ({', '.join(self.broken)}) over the last "
            f"{self.poses} poses: mean NIS {self.mean_nis:.1f} (limit {self.nis_bound:.2f}), "
            f"gated {100 * self.gated_fraction:.0f} % (limit "
            f"{100 * self.max_gated_fraction:.0f} %), RMS position innovation "
            f"{1e3 * self.rms_innovation_m:.1f} mm (limit {1e3 * self.innovation_bound_m:.1f} mm)"
        )


class ConsistencyWatch:
    """Judges each pose's innovation over a sliding window; reports the first breach.

    Args:
        limits: What to judge against.
    """

    def __init__(self, limits: ConsistencyLimits) -> None:
        self.limits = limits
        self._nis: deque[float] = deque(maxlen=limits.window)
        self._sq: deque[float] = deque(maxlen=limits.window)
        self._gated: deque[bool] = deque(maxlen=limits.window)
        self.breach: ConsistencyBreach | None = None
        """The first breach, once one happened (later windows are not judged)."""
        self.worst_mean_nis = 0.0
        """The largest window mean NIS judged so far (the margin a run kept)."""

    def pose(
        self, t_ns: int, nis: float, position_m: float, gated: bool
    ) -> ConsistencyBreach | None:
        """Take one judged pose; return the breach if this pose made the first one.

        Args:
            t_ns: The pose's stamp (ns).
            nis: Its normalized innovation squared (inf: S not positive definite).
            position_m: |position innovation| (m).
            gated: The gate refused it.
        """
        if self.breach is not None or math.isnan(nis) or math.isnan(position_m):
            return None
        lim = self.limits
        self._nis.append(min(nis, 1e12))
        self._sq.append(position_m * position_m)
        self._gated.append(bool(gated))
        n = len(self._nis)
        if n < lim.min_poses:
            return None
        mean_nis = math.fsum(self._nis) / n
        self.worst_mean_nis = max(self.worst_mean_nis, mean_nis)
        candidate = ConsistencyBreach(
            t_ns=int(t_ns),
            poses=n,
            mean_nis=mean_nis,
            nis_bound=nis_bound(n),
            gated_fraction=sum(self._gated) / n,
            max_gated_fraction=lim.max_gated_fraction,
            rms_innovation_m=math.sqrt(math.fsum(self._sq) / n),
            innovation_bound_m=lim.innovation_bound_m,
        )
        if not candidate.broken:
            return None
        self.breach = candidate
        return candidate
