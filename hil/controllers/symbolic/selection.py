"""Choosing one input among the safe ones: the paper's cost J (PAPER.md, Sec. III-A, V-D).

    beta_i = [sigma_i; sigma_i - sigma_pre],   J(sigma_i) = beta_i^T W_i beta_i,
    W_i = diag(7.5, 3, 1, 1, 1, 2.5) if surge(sigma_i) < 0 else diag(1, 6, 1, 1, 1, 2.5)

Backward motion is penalized, sway discouraged and yaw-rate changes smoothed.
"""

from __future__ import annotations

import numpy as np

from hil.controllers.symbolic.errors import EmptyInputSetError
from hil.core.arrays import FloatArray

__all__ = ["W_BACKWARD", "W_FORWARD", "cheapest", "cost", "select"]

W_BACKWARD: FloatArray = np.array([7.5, 3.0, 1.0, 1.0, 1.0, 2.5])
"""Diagonal of W for inputs with negative surge."""
W_FORWARD: FloatArray = np.array([1.0, 6.0, 1.0, 1.0, 1.0, 2.5])
"""Diagonal of W otherwise."""


def cost(candidates: FloatArray, previous: FloatArray | None = None) -> FloatArray:
    """Return J for each candidate, shape (n,).

    Args:
        candidates: Inputs (u m/s, v m/s, r rad/s), shape (n, 3).
        previous: The previous choice, shape (3,); zeros if None.
    """
    sigma = np.asarray(candidates, dtype=np.float64).reshape(-1, 3)
    prev = np.zeros(3) if previous is None else np.asarray(previous, dtype=np.float64).reshape(3)
    beta = np.concatenate([sigma, sigma - prev], axis=1)
    weights = np.where(sigma[:, :1] < 0.0, W_BACKWARD, W_FORWARD)
    out: FloatArray = np.sum(weights * beta * beta, axis=1)
    return out


def cheapest(candidates: FloatArray, previous: FloatArray | None = None) -> int:
    """Return the row of `candidates` (n >= 1, 3) that minimizes J; the first one on ties."""
    return int(np.argmin(cost(candidates, previous)))


def select(safe_inputs: FloatArray, previous: FloatArray | None = None) -> FloatArray:
    """Return argmin J over the safe inputs, shape (3,); the first one on ties.

    Raises:
        EmptyInputSetError: No safe input to choose from.
    """
    sigma = np.asarray(safe_inputs, dtype=np.float64).reshape(-1, 3)
    if sigma.shape[0] == 0:
        raise EmptyInputSetError(f"no safe input to select from (previous {previous!r})")
    out: FloatArray = sigma[cheapest(sigma, previous)].copy()
    return out
