"""NumPy twins and checks shared by the allocation tests, written from the thruster layout."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hil.model.thrusters import VOYAGER_THRUSTERS, thruster_force

F = NDArray[np.float64]
TP = VOYAGER_THRUSTERS.as_array()
FMAX = np.array([0.7 * 2.629, 1.03, 1.03])


def be_twin() -> F:
    """B_e from the thruster positions: tunnel fy; each azimuth fx, fy."""
    lx_t, (lx_p, ly_p), (lx_s, ly_s) = 0.3875, (-0.4574, -0.055), (-0.4574, 0.055)
    return np.array(
        [
            [0.0, 1.0, 0.0, 1.0, 0.0],
            [1.0, 0.0, 1.0, 0.0, 1.0],
            [lx_t, -ly_p, lx_p, -ly_s, lx_s],
        ]
    )


BE = be_twin()


def random_feasible_xi(rng: np.random.Generator, fill: float) -> F:
    """A random extended force within `fill` times the limits."""
    xi = np.empty(5)
    xi[0] = rng.uniform(-1, 1) * FMAX[0] * fill
    for j in range(2):
        r = math.sqrt(rng.uniform()) * FMAX[1 + j] * fill
        a = rng.uniform(-math.pi, math.pi)
        xi[1 + 2 * j : 3 + 2 * j] = (r * math.cos(a), r * math.sin(a))
    return xi


def residual_twin(tau: F, wq: F) -> F:
    """Least weighted residual over the feasible set for each row of tau (B, 3).

    Brute force: plain (unaccelerated) projected gradient written here with numpy,
    run long, all demands at once.
    """
    h = BE.T @ np.diag(wq**2) @ BE
    g = tau @ np.diag(wq**2) @ BE  # (B, 5)
    step = 1.0 / np.linalg.eigvalsh(h).max()
    x = np.zeros((tau.shape[0], 5))
    for _ in range(20000):
        x = x - step * (x @ h - g)
        x[:, 0] = np.clip(x[:, 0], -FMAX[0], FMAX[0])
        for j in range(2):
            f = x[:, 1 + 2 * j : 3 + 2 * j]
            n = np.maximum(np.hypot(f[:, 0], f[:, 1]), 1e-300)
            f *= np.minimum(1.0, FMAX[1 + j] / n)[:, None]
    out: F = np.linalg.norm((x @ BE.T - tau) * wq, axis=1)
    return out


def applied(commands: F, angles: F) -> F:
    return thruster_force(TP, commands, angles)


def check_limits(commands: F) -> None:
    assert abs(commands[0]) <= 0.7 + 1e-12
    assert np.all(np.abs(commands[1:]) <= 1.0 + 1e-12)
