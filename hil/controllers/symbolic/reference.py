"""A straightforward dense solver on the same tables: numpy over all cells and inputs.

It is the baseline of the benchmark and a second opinion in the tests: every iteration
tests every cell under every input with 3-D prefix sums of the winning set, no
frontier, no bit packing. Memory: the tube test is precomputed per (heading, input)
as a bool array of shape (npsi, m, nx, ny).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.abstraction import Tables

BoolArray = NDArray[np.bool_]
I32Array = NDArray[np.int32]

__all__ = ["dense_fixed_point", "dense_tube_free"]


def dense_tube_free(tables: Tables, obstacles: BoolArray) -> BoolArray:
    """Return (npsi, m, nx, ny) bool: the input's swept tube from cell (i, j, k) is free."""
    g = tables.grid
    nx, ny = g.nx, g.ny
    pad = (
        int(max(np.abs(tables.tube_x0).max() + tables.tube_n.max(), np.abs(tables.tube_y).max()))
        + 1
    )
    blocked = np.ones((nx + 2 * pad, ny + 2 * pad), dtype=np.int64)
    blocked[pad : pad + nx, pad : pad + ny] = obstacles
    col = np.zeros((blocked.shape[0], blocked.shape[1] + 1), dtype=np.int64)
    np.cumsum(blocked, axis=1, out=col[:, 1:])
    ii = np.arange(nx)[:, None] + pad
    jj = np.arange(ny)[None, :] + pad
    out = np.ones((g.npsi, tables.n_inputs, nx, ny), dtype=bool)
    for k in range(g.npsi):
        for u in range(tables.n_inputs):
            for c in range(int(tables.tube_n[k, u])):
                x = ii + tables.tube_x0[k, u] + c
                y0 = jj + tables.tube_y[k, u, c, 0]
                y1 = jj + tables.tube_y[k, u, c, 1]
                out[k, u] &= (col[x, y1 + 1] - col[x, y0]) == 0
    return out


def dense_fixed_point(
    tables: Tables, obstacles: BoolArray, target: BoolArray, max_iterations: int | None = None
) -> tuple[I32Array, int]:
    """Return V (nx, ny, npsi; -1 losing) and the iterations, by dense Jacobi sweeps.

    Args:
        tables: The abstraction.
        obstacles: Obstacle cells, shape (nx, ny).
        target: Target cells, shape (nx, ny).
        max_iterations: Stop after this many sweeps (for timing a few); None runs to the end.
    """
    g = tables.grid
    nx, ny, npsi = g.shape
    free = ~obstacles
    tube_free = dense_tube_free(tables, obstacles)
    succ = tables.succ
    head = tables.heading
    pad = int(np.abs(succ).max()) + 1
    values = np.full((nx, ny, npsi), -1, dtype=np.int32)
    values[target & free] = 0
    ks = np.arange(npsi)
    ii = np.arange(nx)[:, None, None] + pad
    jj = np.arange(ny)[None, :, None] + pad
    level = 0
    while max_iterations is None or level < max_iterations:
        win = values >= 0
        # Prefix sums over a padded copy: outside the grid counts as losing; headings
        # are tiled three times so that every wrapped range is contiguous.
        padded = np.zeros((nx + 2 * pad, ny + 2 * pad, 3 * npsi), dtype=np.int32)
        padded[pad : pad + nx, pad : pad + ny] = np.concatenate([win, win, win], axis=2)
        s = np.zeros(
            (padded.shape[0] + 1, padded.shape[1] + 1, padded.shape[2] + 1), dtype=np.int32
        )
        s[1:, 1:, 1:] = padded.cumsum(0).cumsum(1).cumsum(2)
        joins = np.zeros((nx, ny, npsi), dtype=bool)
        for u in range(tables.n_inputs):
            x0 = ii + succ[:, u, 0][None, None, :]
            x1 = ii + succ[:, u, 1][None, None, :] + 1
            y0 = jj + succ[:, u, 2][None, None, :]
            y1 = jj + succ[:, u, 3][None, None, :] + 1
            z0 = (ks + npsi + head[u, 0])[None, None, :]
            z1 = (ks + npsi + head[u, 1] + 1)[None, None, :]
            count = (
                s[x1, y1, z1]
                - s[x0, y1, z1]
                - s[x1, y0, z1]
                - s[x1, y1, z0]
                + s[x0, y0, z1]
                + s[x0, y1, z0]
                + s[x1, y0, z0]
                - s[x0, y0, z0]
            )
            volume = (x1 - x0) * (y1 - y0) * (z1 - z0)
            joins |= (count == volume) & np.moveaxis(tube_free[:, u], 0, -1)
        joins &= ~win & free[:, :, None]
        if not joins.any():
            break
        level += 1
        values[joins] = level
    return values, level
