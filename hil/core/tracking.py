"""Velocity-tracking error: the one definition of join, units and sign.

The error is ``e = nu - nu_ref`` (body frame: surge u m/s, sway v m/s, yaw rate
r rad/s), positive when the vessel is faster than commanded. Each velocity
sample is joined with the reference *in force at its time*: the newest
reference stamped at or before the sample (zero-order hold, as the loop holds
``nu_ref`` between decisions). Samples before the first reference have no
reference and are left out. When the velocity and reference come from the same
loop ticks (the runtime logs both at each tick under control) this is the
same-tick pairing.

Everything here is SI (rad/s for yaw); :func:`for_display` turns a yaw column
into deg/s, the unit the paper prints, for reports and plots only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hil.core.arrays import FloatArray, IntArray
from hil.core.timeline import in_force

AXES = ("surge", "sway", "yaw")
"""Axis names, in the column order of every (N, 3) velocity array."""
DISPLAY_UNITS = ("m/s", "m/s", "deg/s")
"""Units of :func:`for_display` per axis."""


def for_display(values: FloatArray) -> FloatArray:
    """Return `values` with the yaw column in deg/s instead of rad/s.

    Args:
        values: Per-axis values in SI, shape (3,) or (N, 3).

    Returns:
        A copy of the same shape; surge and sway unchanged (m/s).
    """
    out = np.array(values, dtype=np.float64, copy=True)
    out[..., 2] = np.degrees(out[..., 2])
    return out


@dataclass(frozen=True, slots=True)
class TrackingSeries:
    """The tracking error at each joined velocity sample.

    Attributes:
        t_ns: Times of the velocity samples (ns), shape (N,), as given (ascending
            when the inputs are).
        error: ``nu - nu_ref`` in SI (m/s, m/s, rad/s), shape (N, 3), time-major.
    """

    t_ns: IntArray
    error: FloatArray

    def __len__(self) -> int:
        """Return the number of joined samples N."""
        return int(self.t_ns.shape[0])

    def rms(self) -> FloatArray:
        """Return the RMS per axis (SI), shape (3,); NaN without samples."""
        if not len(self):
            return np.full(3, math.nan)
        return np.asarray(np.sqrt(np.mean(self.error**2, axis=0)), dtype=np.float64)

    def peak(self) -> tuple[FloatArray, IntArray]:
        """Return the largest |error| per axis (SI) (3,) and its first time (ns) (3,).

        Without samples: NaN and 0.
        """
        if not len(self):
            return np.full(3, math.nan), np.zeros(3, np.int64)
        k = np.argmax(np.abs(self.error), axis=0)
        return np.abs(self.error[k, [0, 1, 2]]), self.t_ns[k]


def tracking_error(
    t_ns: IntArray, nu: FloatArray, ref_t_ns: IntArray, nu_ref: FloatArray
) -> TrackingSeries:
    """Join velocities with the reference in force at their time; return ``nu - nu_ref``.

    Args:
        t_ns: Velocity sample times (ns), shape (N,).
        nu: Velocities (u m/s, v m/s, r rad/s), shape (N, 3).
        ref_t_ns: Reference times (ns), shape (M,), ascending.
        nu_ref: References (u m/s, v m/s, r rad/s), shape (M, 3).

    Returns:
        The error at every velocity sample stamped at or after the first
        reference, each against the newest reference stamped at or before it.

    Raises:
        ValueError: Shapes that do not match, or reference times not ascending.
    """
    t = np.asarray(t_ns, dtype=np.int64).reshape(-1)
    v = np.asarray(nu, dtype=np.float64).reshape(-1, 3)
    rt = np.asarray(ref_t_ns, dtype=np.int64).reshape(-1)
    rv = np.asarray(nu_ref, dtype=np.float64).reshape(-1, 3)
    if len(t) != len(v) or len(rt) != len(rv):
        raise ValueError(
            f"times and values differ in length: nu {len(t)} vs {len(v)}, "
            f"nu_ref {len(rt)} vs {len(rv)}"
        )
    if np.any(rt[1:] < rt[:-1]):
        raise ValueError("reference times must be ascending")
    held = in_force(rt, t)
    keep = held >= 0
    return TrackingSeries(t[keep], v[keep] - rv[held[keep]])
