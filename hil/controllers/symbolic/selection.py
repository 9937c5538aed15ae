"""Choosing one input among the safe ones: the paper's cost J (PAPER.md, Sec. III-A, V-D).

    beta_i = [sigma_i; sigma_i - sigma_pre],   J(sigma_i) = beta_i^T W_i beta_i,
    W_i = diag(7.5, 3, 1, 1, 1, 2.5) if surge(sigma_i) < 0 else diag(1, 6, 1, 1, 1, 2.5)

Backward motion is penalized, sway discouraged and yaw-rate changes smoothed.
"""

from __future__ import annotations

import numpy as np

from hil.controllers.symbolic.errors import EmptyInputSetError
from hil.core.arrays import FloatArray

__all__ = ["W_BACKWARD", "W_FORWARD", "cost", "select", "wait_index"]

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


def select(safe_inputs: FloatArray, previous: FloatArray | None = None) -> FloatArray:
    """Return argmin J over the safe inputs, shape (3,); the first one on ties.

    Raises:
        EmptyInputSetError: No safe input to choose from.
    """
    sigma = np.asarray(safe_inputs, dtype=np.float64).reshape(-1, 3)
    if sigma.shape[0] == 0:
        raise EmptyInputSetError(f"no safe input to select from (previous {previous!r})")
    out: FloatArray = sigma[int(np.argmin(cost(sigma, previous)))].copy()
    return out


def wait_index(
    staying_inputs: FloatArray,
    _previous: FloatArray | None = None,
    _state: FloatArray | None = None,
) -> int:
    """Return the row of `staying_inputs` (k, 3) a waiting vessel flies: the slowest by J.

    Waiting on the safety controller (docking not winning), the vessel slows toward
    rest: J against rest (previous input zero) weighs speed with the paper's weights
    (backward and sway dearer), and the lattice keeps each change to one step. The
    previous input and the state, which other selections take, are not used.
    """
    return int(np.argmin(cost(staying_inputs, np.zeros(3))))
