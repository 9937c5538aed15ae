"""The array types of hil's public APIs (numpy arrays; shapes and units in each docstring)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["BoolArray", "FloatArray", "IntArray", "U64Array"]

FloatArray = NDArray[np.float64]
"""float64 arrays: positions (m), angles (rad), velocities, forces, times in s."""

IntArray = NDArray[np.int64]
"""int64 arrays: time stamps (ns), indices, counts."""

BoolArray = NDArray[np.bool_]
"""Masks."""

U64Array = NDArray[np.uint64]
"""Bit words of the symbolic controller's sets."""
