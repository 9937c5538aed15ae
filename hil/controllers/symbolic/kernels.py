"""Compiled kernels of the controller: bit packing, values and the safe-input lookup.

The winning sets and values are in the fixed point's own bit layout (:mod:`planes_kernel`),
layer-major with x contiguous: W of shape (m, npsi, nw + 2 pw, nx + 2 px), value bit
planes of shape (m, npsi, nw, n_planes, nx), so a finished solve hands its arrays over
without a copy; viable words of shape (3, m, npsi, nw, nx) (:mod:`viable`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hil.core.arrays import BoolArray, U64Array
from hil.core.jit import njit

I32Array = NDArray[np.int32]

__all__ = [
    "first_decision_cells",
    "layer_values",
    "pack_rows",
    "safe_input_indices",
    "state_value",
    "state_values",
    "staying_input_indices",
]

_ZERO = np.uint64(0)
_ONE = np.uint64(1)


@njit
def pack_rows(mask: BoolArray) -> U64Array:
    """Pack a bool array (rows, ny) into bits, shape (rows, ceil(ny / 64)).

    Branch-free, one word at a time (0.3x the time of setting bit by bit: a layout's
    free masks are 17 MB of bools at the paper grid, packed on the way to every solve).
    """
    n_rows, ny = mask.shape
    nw = (ny + 63) // 64
    out = np.empty((n_rows, nw), dtype=np.uint64)
    for r in range(n_rows):
        for w in range(nw):
            n = min(64, ny - 64 * w)
            bits = mask[r, 64 * w : 64 * w + n]
            word = _ZERO
            for b in range(n):
                word |= np.uint64(bits[b]) << np.uint64(b)
            out[r, w] = word
    return out


@njit
def state_value(
    W: U64Array, planes: U64Array, pads: I32Array, p: int, i: int, j: int, k: int
) -> int:
    """Return the value of state (cell (i, j, k), reference p); -1 if losing or off the grid.

    W (m, npsi, nw + 2 pw, nx + 2 px) and planes (m, npsi, nw, n_planes, nx) are in the
    fixed point's own layout (:mod:`planes_kernel`); pads is (px, ph, pw), ph unused.
    """
    _, npsi, nw, n_planes, nx = planes.shape
    if i < 0 or i >= nx or j < 0 or j >= 64 * nw:
        return -1
    kk = k % npsi
    w = j >> 6
    b = np.uint64(j & 63)
    if (W[p, kk, pads[2] + w, pads[0] + i] >> b) & _ONE == _ZERO:
        return -1
    v = 0
    for q in range(n_planes):
        if (planes[p, kk, w, q, i] >> b) & _ONE != _ZERO:
            v |= 1 << q
    return v


@njit
def state_values(
    W: U64Array,
    planes: U64Array,
    pads: I32Array,
    p: int,
    i: NDArray[np.int64],
    j: NDArray[np.int64],
    k: NDArray[np.int64],
) -> NDArray[np.int64]:
    """Return the values of states (i[n], j[n], k[n]) in layer p, shape (N,); -1 losing."""
    out = np.empty(i.shape[0], dtype=np.int64)
    for n in range(i.shape[0]):
        out[n] = state_value(W, planes, pads, p, i[n], j[n], k[n])
    return out


@njit
def layer_values(W: U64Array, planes: U64Array, pads: I32Array, p: int, ny: int) -> I32Array:
    """Return the values of layer p, shape (nx, ny, npsi); -1 marks losing cells."""
    npsi, nx = planes.shape[1], planes.shape[4]
    out = np.full((nx, ny, npsi), -1, dtype=np.int32)
    for i in range(nx):
        for k in range(npsi):
            for j in range(ny):
                out[i, j, k] = state_value(W, planes, pads, p, i, j, k)
    return out


@njit
def safe_input_indices(
    W: U64Array,
    planes: U64Array,
    viable: U64Array,
    pads: I32Array,
    succ: I32Array,
    heading: I32Array,
    neighbours: I32Array,
    n_neighbours: I32Array,
    ny: int,
    p: int,
    i: int,
    j: int,
    k: int,
    first: bool,
    out: I32Array,
    best: I32Array,
    worsts: I32Array,
    any_only: bool = False,
) -> int:
    """Write the safe inputs at cell (i, j, k) with reference p in force to `out`; return n.

    Candidates are p (class 0, hold) and its neighbours (class 1, change); with `first`
    (the run's first command, the vessel possibly moving) every candidate is class 2.
    Safe: the tube is free (viable) and every successor cell is winning in the input's
    layer with a value strictly below the state's (any value with `first`). None at a
    losing or target state (unless `first`, where the state's own value is not used).
    best[0] is set to 1 + the least, over the safe inputs, of their largest successor
    value (the value a first decision earns), -1 with none; worsts[n] to the n-th safe
    input's largest successor value.
    """
    best[0] = -1
    vc = state_value(W, planes, pads, p, i, j, k)
    if not first and vc <= 0:
        return 0
    if vc == 0:
        best[0] = 0
        return 0  # in the target: hold position
    limit = vc if (not first and vc > 0) else 1 << 30
    n = 0
    w = j >> 6
    b = np.uint64(j & 63)
    for c_idx in range(n_neighbours[p] + 1):
        u = p if c_idx == 0 else neighbours[p, c_idx - 1]
        cls = 2 if first else (0 if u == p else 1)
        if (viable[cls, u, k, w, i] >> b) & _ONE == _ZERO:
            continue
        worst = _worst_successor(W, planes, pads, succ, heading, ny, cls, u, i, j, k, limit)
        if worst >= 0:
            out[n] = u
            worsts[n] = worst
            n += 1
            if best[0] < 0 or worst + 1 < best[0]:
                best[0] = worst + 1
            if any_only:
                break
    return n


@njit
def _worst_successor(
    W: U64Array,
    planes: U64Array,
    pads: I32Array,
    succ: I32Array,
    heading: I32Array,
    ny: int,
    cls: int,
    u: int,
    i: int,
    j: int,
    k: int,
    limit: int,
) -> int:
    """Return the largest value over input u's class-cls successors of (i, j, k).

    -1 if any successor is off the grid, losing (not in W's layer u) or of value >= limit.
    """
    npsi = planes.shape[1]
    worst = 0
    for ox in range(succ[cls, k, u, 0], succ[cls, k, u, 1] + 1):
        for oy in range(succ[cls, k, u, 2], succ[cls, k, u, 3] + 1):
            jj = j + oy
            if jj < 0 or jj >= ny:
                return -1
            for ok in range(heading[cls, u, 0], heading[cls, u, 1] + 1):
                v = state_value(W, planes, pads, u, i + ox, jj, (k + ok) % npsi)
                if v < 0 or v >= limit:
                    return -1
                worst = max(worst, v)
    return worst


@njit
def staying_input_indices(
    S: U64Array,
    no_planes: U64Array,
    viable: U64Array,
    pads: I32Array,
    succ: I32Array,
    heading: I32Array,
    neighbours: I32Array,
    n_neighbours: I32Array,
    ny: int,
    p: int,
    i: int,
    j: int,
    k: int,
    first: bool,
    out: I32Array,
) -> int:
    """Write the inputs at cell (i, j, k), reference p, that keep the state in S; return n.

    S is the safety game's set (:mod:`safety`) in the winning bits' layout; no_planes an
    array of shape (m, npsi, nw, 0, nx) (a state of S has "value" 0). Candidates and
    classes as in :func:`safe_input_indices`; an input stays when its tube is free and
    every successor is in S's layer of that input. The state itself need not be in S
    (a first decision's moving start).
    """
    n = 0
    w = j >> 6
    b = np.uint64(j & 63)
    for c_idx in range(n_neighbours[p] + 1):
        u = p if c_idx == 0 else neighbours[p, c_idx - 1]
        cls = 2 if first else (0 if u == p else 1)
        if (viable[cls, u, k, w, i] >> b) & _ONE == _ZERO:
            continue
        if _worst_successor(S, no_planes, pads, succ, heading, ny, cls, u, i, j, k, 1) >= 0:
            out[n] = u
            n += 1
    return n


@njit
def first_decision_cells(
    W: U64Array,
    planes: U64Array,
    viable: U64Array,
    pads: I32Array,
    succ: I32Array,
    heading: I32Array,
    neighbours: I32Array,
    n_neighbours: I32Array,
    ny: int,
    p: int,
) -> NDArray[np.bool_]:
    """Return where a first decision with reference p in force finds a safe input.

    Shape (nx, ny, npsi): :func:`safe_input_indices` with `first` (every candidate
    budgeted as a first command, into the winning set at any value) has an input, or
    the cell is in the target (value 0: hold).
    """
    npsi, nx = planes.shape[1], planes.shape[4]
    out = np.zeros((nx, ny, npsi), dtype=np.bool_)
    found = np.empty(neighbours.shape[1] + 1, dtype=np.int32)
    worsts = np.empty(neighbours.shape[1] + 1, dtype=np.int32)
    best = np.empty(1, dtype=np.int32)
    for i in range(nx):
        for j in range(ny):
            for k in range(npsi):
                safe_input_indices(
                    W, planes, viable, pads, succ, heading, neighbours, n_neighbours, ny,
                    p, i, j, k, True, found, best, worsts, True,
                )  # fmt: skip
                out[i, j, k] = best[0] >= 0
    return out
