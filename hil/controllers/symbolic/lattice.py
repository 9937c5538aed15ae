"""The input grid as a lattice: which references may follow which.

The symbolic layer may change the velocity reference by at most one grid step per axis
per command period (issue 11: the low level's transient is budgeted only for such
changes). The inputs are the scenario's grid in C order over (surge, sway, yaw rate),
as :meth:`hil.scenarios.Scenario.inputs` builds it; input index
``(a * n_sway + b) * n_yaw + c`` has axis indices (a, b, c).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.errors import GridError
from hil.core.arrays import FloatArray

I32Array = NDArray[np.int32]

__all__ = ["InputLattice"]

_REL = 1e-9  # relative slack when recognising grid values


@dataclass(frozen=True, slots=True, eq=False)
class InputLattice:
    """The inputs' axes and one-step neighbourhoods.

    Attributes:
        axes: Values of each axis (surge m/s, sway m/s, yaw rate rad/s), each ascending.
        index: Axis indices of every input, shape (m, 3).
        neighbours: For each input u, the inputs within one step per axis other than u,
            shape (m, 26), padded with -1; ``neighbours[u, :n_neighbours[u]]``.
        n_neighbours: Shape (m,).
    """

    axes: tuple[FloatArray, FloatArray, FloatArray]
    index: I32Array
    neighbours: I32Array
    n_neighbours: I32Array

    @staticmethod
    def of(inputs: FloatArray) -> InputLattice:
        """Recognise the lattice of an (m, 3) input array in the scenario's order.

        Raises:
            GridError: The inputs are not a full grid in C order over (surge, sway, yaw).
        """
        arr = np.asarray(inputs, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0:
            raise GridError(f"inputs must have shape (m, 3), got {arr.shape!r}")
        axes = tuple(np.unique(arr[:, d]) for d in range(3))
        sizes = tuple(len(a) for a in axes)
        if int(np.prod(sizes)) != arr.shape[0]:
            raise GridError(f"inputs are not a full grid: {arr.shape[0]} rows, axes {sizes!r}")
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        if not np.allclose(grid, arr, rtol=_REL, atol=0.0):
            raise GridError("inputs are not in the grid's C order over (surge, sway, yaw rate)")
        index = np.stack(
            np.meshgrid(*(np.arange(n) for n in sizes), indexing="ij"), axis=-1
        ).reshape(-1, 3)
        n_in = arr.shape[0]
        neighbours = np.full((n_in, 26), -1, dtype=np.int32)
        counts = np.zeros(n_in, dtype=np.int32)
        steps = [s for s in itertools.product((-1, 0, 1), repeat=3) if s != (0, 0, 0)]
        for u in range(n_in):
            for s in steps:
                a, b, c = (int(index[u, d] + s[d]) for d in range(3))
                if 0 <= a < sizes[0] and 0 <= b < sizes[1] and 0 <= c < sizes[2]:
                    neighbours[u, counts[u]] = (a * sizes[1] + b) * sizes[2] + c
                    counts[u] += 1
        return InputLattice(
            axes=(axes[0], axes[1], axes[2]),
            index=index.astype(np.int32),
            neighbours=neighbours,
            n_neighbours=counts,
        )

    @property
    def n_inputs(self) -> int:
        """Return m."""
        return int(self.index.shape[0])

    def allowed_after(self, previous: int) -> I32Array:
        """Return the inputs that may follow input `previous`, itself first, shape (n,)."""
        n = int(self.n_neighbours[previous])
        return np.concatenate([[previous], self.neighbours[previous, :n]]).astype(np.int32)

    def nearest(self, velocity: FloatArray) -> int:
        """Return the input nearest a body velocity (u, v, r) per axis (clipped to the grid)."""
        nu = np.asarray(velocity, dtype=np.float64).reshape(3)
        idx = [int(np.argmin(np.abs(self.axes[d] - nu[d]))) for d in range(3)]
        return (idx[0] * len(self.axes[1]) + idx[1]) * len(self.axes[2]) + idx[2]

    def distance_steps(self, a: int, b: int) -> int:
        """Return the largest per-axis distance between inputs a and b in grid steps."""
        return int(np.abs(self.index[a] - self.index[b]).max())
