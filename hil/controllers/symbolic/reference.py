"""A straightforward dense solver of the same game: numpy over all states and inputs.

It is a second opinion in the tests and the baseline of the benchmark: every level tests
every (cell, input) pair of both budget classes with 3-D prefix sums of each layer's
winning set, no frontier, no bit packing, no shared code with :mod:`sweep` beyond the
tables and the free masks. The game (see :mod:`sweep`): a state (cell, p) joins at level
L + 1 if holding p (class 0) or moving to a one-step neighbour u of p (class 1) has a
free tube and all successor cells winning with u in force at level <= L.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.abstraction import Tables
from hil.controllers.symbolic.lattice import InputLattice
from hil.core.arrays import BoolArray

I32Array = NDArray[np.int32]

__all__ = ["dense_fixed_point", "dense_tube_free"]


def dense_tube_free(tables: Tables, free: BoolArray) -> BoolArray:
    """Return (3, m, nx, ny, npsi) bool: the class-c tube of input u from the cell is free.

    Args:
        tables: The abstraction.
        free: Cells free for the hull over each of the tables' heading ranges, shape
            (n_ranges, nx, ny) (``tables.hull_psi`` flattened).
    """
    g = tables.grid
    nx, ny, npsi = g.shape
    pad = int(max(np.abs(tables.tube_x0).max() + tables.tube_n.max(), np.abs(tables.tube_y).max()))
    pad += 1
    ranges = tables.hull_range_index()
    ii = np.arange(nx)[:, None] + pad
    jj = np.arange(ny)[None, :] + pad
    n_cls = tables.succ.shape[0]
    out = np.ones((n_cls, tables.n_inputs, nx, ny, npsi), dtype=bool)
    prefix: dict[int, NDArray[np.int64]] = {}
    for c in range(n_cls):
        for k in range(npsi):
            for u in range(tables.n_inputs):
                h = int(ranges[c, k, u])
                if h not in prefix:
                    blocked = np.ones((nx + 2 * pad, ny + 2 * pad), dtype=np.int64)
                    blocked[pad : pad + nx, pad : pad + ny] = ~free[h]
                    col = np.zeros((blocked.shape[0], blocked.shape[1] + 1), dtype=np.int64)
                    np.cumsum(blocked, axis=1, out=col[:, 1:])
                    prefix[h] = col
                col = prefix[h]
                ok = np.ones((nx, ny), dtype=bool)
                for cc in range(int(tables.tube_n[c, k, u])):
                    x = ii + tables.tube_x0[c, k, u] + cc
                    y0 = jj + tables.tube_y[c, k, u, cc, 0]
                    y1 = jj + tables.tube_y[c, k, u, cc, 1]
                    ok &= (col[x, y1 + 1] - col[x, y0]) == 0
                out[c, u, :, :, k] = ok
    return out


def _boxes_winning(win: BoolArray, succ: I32Array, head: I32Array, u: int, pad: int) -> BoolArray:
    """Return (nx, ny, npsi): input u's successor box lies wholly in `win` (nx, ny, npsi).

    succ has shape (npsi, m, 4), head (m, 2); outside the grid is losing.
    """
    nx, ny, npsi = win.shape
    # Heading offsets may exceed a full circle (fast turns): enough copies of the
    # headings on each side that every offset reads a copy.
    wraps = max(1, -(-int(np.abs(head[u]).max()) // npsi))
    reps = 2 * wraps + 1
    padded = np.zeros((nx + 2 * pad, ny + 2 * pad, reps * npsi), dtype=np.int32)
    padded[pad : pad + nx, pad : pad + ny] = np.concatenate([win] * reps, axis=2)
    s = np.zeros((padded.shape[0] + 1, padded.shape[1] + 1, padded.shape[2] + 1), dtype=np.int32)
    s[1:, 1:, 1:] = padded.cumsum(0).cumsum(1).cumsum(2)
    ii = np.arange(nx)[:, None, None] + pad
    jj = np.arange(ny)[None, :, None] + pad
    ks = np.arange(npsi)
    x0 = ii + succ[:, u, 0][None, None, :]
    x1 = ii + succ[:, u, 1][None, None, :] + 1
    y0 = jj + succ[:, u, 2][None, None, :]
    y1 = jj + succ[:, u, 3][None, None, :] + 1
    z0 = (ks + wraps * npsi + head[u, 0])[None, None, :]
    z1 = (ks + wraps * npsi + head[u, 1] + 1)[None, None, :]
    count = (
        s[x1, y1, z1] - s[x0, y1, z1] - s[x1, y0, z1] - s[x1, y1, z0]
        + s[x0, y0, z1] + s[x0, y1, z0] + s[x1, y0, z0] - s[x0, y0, z0]
    )  # fmt: skip
    out: BoolArray = count == (x1 - x0) * (y1 - y0) * (z1 - z0)
    return out


def dense_fixed_point(
    tables: Tables,
    free: BoolArray,
    target: BoolArray,
    max_levels: int | None = None,
    tube: BoolArray | None = None,
) -> tuple[I32Array, int]:
    """Return V (m, nx, ny, npsi) indexed [reference, i, j, k] (-1 losing) and the levels.

    Args:
        tables: The abstraction.
        free: Free cells per heading range, shape (n_ranges, nx, ny).
        target: Target cells, shape (nx, ny, npsi).
        max_levels: Stop after this many levels (for timing a few); None runs to the end.
        tube: :func:`dense_tube_free` of `free`, if already computed.
    """
    lattice = InputLattice.of(tables.inputs)
    m = tables.n_inputs
    if tube is None:
        tube = dense_tube_free(tables, free)
    pad = int(np.abs(tables.succ).max()) + 1
    values = np.full((m, *target.shape), -1, dtype=np.int32)
    values[:, target] = 0
    level = 0
    while max_levels is None or level < max_levels:
        win = values >= 0
        hold = np.zeros_like(win)
        change = np.zeros_like(win)
        for u in range(m):
            hold[u] = tube[0, u] & _boxes_winning(win[u], tables.succ[0], tables.heading[0], u, pad)
            change[u] = tube[1, u] & _boxes_winning(
                win[u], tables.succ[1], tables.heading[1], u, pad
            )
        joins = hold.copy()
        for p in range(m):
            for u in lattice.neighbours[p, : lattice.n_neighbours[p]]:
                joins[p] |= change[u]
        joins &= ~win
        if not joins.any():
            break
        level += 1
        values[joins] = level
    return values, level
