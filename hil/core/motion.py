"""Scheduled obstacle motion: constant-velocity spans of one obstacle, and where they take it.

An :class:`ObstacleMotion` moves obstacle ``index`` (its position in the layout) at a
constant arena-frame velocity from ``start_s`` to ``stop_s`` of the run. Motions of one
obstacle add up: its displacement at time t is the sum over its motions of velocity x
the part of [start_s, stop_s] before t, so back and forth is two motions one after the
other. The simulator's obstacle reports (:mod:`hil.adapters.sim`), the run summary's
clearance and the campaign's guarantee judge all place obstacles by
:func:`displacements_m`, so they agree on where an obstacle truly is.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from hil.core.arrays import FloatArray

__all__ = ["ObstacleMotion", "displacements_m"]


@dataclass(frozen=True, slots=True)
class ObstacleMotion:
    """A scheduled constant-velocity motion of one obstacle.

    Attributes:
        index: Which obstacle (position in the layout).
        velocity_mps: (vx, vy) in the arena frame (m/s).
        start_s: When the motion starts (s, run time).
        stop_s: When it stops (s, run time).
    """

    index: int
    velocity_mps: tuple[float, float]
    start_s: float
    stop_s: float

    def offset_m(self, t_s: float) -> tuple[float, float]:
        """Return the displacement this motion accumulated by time `t_s` (m)."""
        moving_s = min(max(t_s, self.start_s), self.stop_s) - self.start_s
        return self.velocity_mps[0] * moving_s, self.velocity_mps[1] * moving_s


def displacements_m(motions: Sequence[ObstacleMotion], n_obstacles: int,
                    t_s: ArrayLike) -> FloatArray:
    """Return every obstacle's displacement at each time, motions of one obstacle summed.

    Args:
        motions: The scheduled motions; an index outside ``[0, n_obstacles)`` is ignored.
        n_obstacles: Number of obstacles in the layout.
        t_s: Times (s), shape (N,) (a scalar is one time).

    Returns:
        Displacements (dx, dy) in the arena frame (m), shape (n_obstacles, N, 2) indexed
        [obstacle, time, axis]; zero for an obstacle without motions.
    """
    t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
    out = np.zeros((n_obstacles, len(t), 2))
    for m in motions:
        if 0 <= m.index < n_obstacles:
            moving = np.clip(t, m.start_s, m.stop_s) - m.start_s
            out[m.index] += moving[:, None] * np.asarray(m.velocity_mps, dtype=np.float64)
    return out
