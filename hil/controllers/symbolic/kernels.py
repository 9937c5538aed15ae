"""Compiled kernels of the controller: bit packing and the safe-input lookup."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hil.core.jit import njit

U64Array = NDArray[np.uint64]
I32Array = NDArray[np.int32]
BoolArray = NDArray[np.bool_]

__all__ = ["pack_rows", "safe_input_indices"]

_ZERO = np.uint64(0)


@njit
def pack_rows(mask: BoolArray) -> U64Array:
    """Pack a bool array (rows, ny) into bits, shape (rows, ceil(ny / 64))."""
    n_rows, ny = mask.shape
    nw = (ny + 63) // 64
    out = np.zeros((n_rows, nw), dtype=np.uint64)
    for r in range(n_rows):
        for j in range(ny):
            if mask[r, j]:
                out[r, j >> 6] |= np.uint64(1) << np.uint64(j & 63)
    return out


@njit
def safe_input_indices(
    V: NDArray[np.int32],
    obstacle_prefix: I32Array,
    succ: I32Array,
    heading: I32Array,
    tube_x0: I32Array,
    tube_n: I32Array,
    tube_y: I32Array,
    i: int,
    j: int,
    k: int,
    out: I32Array,
) -> int:
    """Write the indices of the safe inputs at cell (i, j, k) to `out`; return how many.

    Safe: the swept tube is obstacle-free and inside the grid, and every successor cell
    is winning with a value strictly below V[i, j, k]. None at a losing or target cell.
    obstacle_prefix[i, j] counts obstacle cells (i, 0 .. j-1), shape (nx, ny + 1).
    """
    nx, ny, npsi = V.shape
    vc = V[i, j, k]
    n = 0
    if vc <= 0:
        return 0
    for u in range(succ.shape[1]):
        ok_input = True
        for ox in range(succ[k, u, 0], succ[k, u, 1] + 1):
            ii = i + ox
            if ii < 0 or ii >= nx:
                ok_input = False
                break
            for oy in range(succ[k, u, 2], succ[k, u, 3] + 1):
                jj = j + oy
                if jj < 0 or jj >= ny:
                    ok_input = False
                    break
                for ok in range(heading[u, 0], heading[u, 1] + 1):
                    v = V[ii, jj, (k + ok) % npsi]
                    if v < 0 or v >= vc:
                        ok_input = False
                        break
                if not ok_input:
                    break
            if not ok_input:
                break
        if not ok_input:
            continue
        for c in range(tube_n[k, u]):
            ii = i + tube_x0[k, u] + c
            j0 = j + tube_y[k, u, c, 0]
            j1 = j + tube_y[k, u, c, 1]
            if ii < 0 or ii >= nx or j0 < 0 or j1 >= ny:
                ok_input = False
                break
            if obstacle_prefix[ii, j1 + 1] - obstacle_prefix[ii, j0] != 0:
                ok_input = False
                break
        if ok_input:
            out[n] = u
            n += 1
    return n
