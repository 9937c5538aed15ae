"""Which sample of a time series is in force at given times: the one rule, in one place."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from hil.core.arrays import IntArray

__all__ = ["in_force"]


def in_force(starts_ns: ArrayLike, t_ns: ArrayLike) -> IntArray:
    """Return, for each time, the index of the newest start at or before it.

    A value takes effect at its own stamp and holds until the next one: a time equal to
    a start is in that start's span.

    Args:
        starts_ns: Start times (ns), shape (M,), ascending.
        t_ns: Query times (ns), shape (N,), any order.

    Returns:
        Shape (N,): indices into `starts_ns`, -1 before the first start (or with none).
    """
    starts = np.asarray(starts_ns, dtype=np.int64).reshape(-1)
    times = np.asarray(t_ns, dtype=np.int64).reshape(-1)
    out: IntArray = np.searchsorted(starts, times, side="right").astype(np.int64) - 1
    return out
