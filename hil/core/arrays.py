"""The array types of hil's public APIs (numpy arrays; shapes and units in each docstring)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["BoolArray", "FloatArray", "IntArray", "U64Array", "finite_vector"]

FloatArray = NDArray[np.float64]
"""float64 arrays: positions (m), angles (rad), velocities, forces, times in s."""

IntArray = NDArray[np.int64]
"""int64 arrays: time stamps (ns), indices, counts."""

BoolArray = NDArray[np.bool_]
"""Masks."""

U64Array = NDArray[np.uint64]
"""Bit words of the symbolic controller's sets."""


def finite_vector(
    name: str,
    value: object,
    n: int,
    shape_error: type[Exception],
    finite_error: type[Exception],
) -> FloatArray:
    """Return `value` as a float64 vector of shape (n,), refusing any other or a NaN/inf.

    Args:
        name: What the value is, for the messages (``"force demand"``).
        value: Anything numpy turns into an array.
        n: The length it must have.
        shape_error: Raised (naming the shape it got) when the shape is not (n,).
        finite_error: Raised (naming the values) when an entry is not finite.
    """
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (n,):
        raise shape_error(f"{name} must have shape ({n},), got {arr.shape!r}")
    if not np.all(np.isfinite(arr)):
        raise finite_error(f"{name} must be finite, got {arr.tolist()!r}")
    return arr
