"""Compiled frontier sweeps of the reach-avoid game over (cell, current reference).

The game's state is a grid cell plus the reference p the low level is tracking (the
previous command); from (cell, p) the controller may command any u within one grid step
per axis of p (:class:`~hil.controllers.symbolic.lattice.InputLattice`). Holding p is
budgeted by the class-0 tables, a change by the class-1 tables, so with

    A_u = Pre0_u(W_u),   B_u = Pre1_u(W_u)   (tube free, successor box inside W_u)

the winning sets of the layers satisfy  W_p = A_p  union  (union over u in N(p) of B_u).
Each level computes A_u and B_u once per input from the layer W_u they need (not once
per (p, u) pair); each layer p then gathers B_u from its up to 26 neighbours.

Layout: W has shape (m, nx + 2 px, npsi + 2 ph, nw + 2 pw) (uint64), layer-major: bit b
of word pw + w in row (px + i, ph + k) of layer p is cell (i, j = 64 w + b, k). A layer
is small (625 KB on the paper grid) and the work of a level is done layer by layer, so
the successor boxes read stay in cache. Padding rows stay zero (not winning: outside
the grid), heading rows k < 0 or k >= npsi copy the rows they wrap to, pw >= 2 + the
largest y offset // 64 (a successor run is read from three words). A successor box
[ox0, ox1] x [oy0, oy1] x [ok0, ok1] of 64 cells at once is, per ox, the AND over the
heading rows k + ok of three words, shifted by oy0 and eroded over the oy1 - oy0 + 1
cells of the run (at most 64).

Rows are numbered r = i * npsi + k; sets of rows are bitsets of shape (m, n_rw) with
n_rw = ceil(nx npsi / 64) (bit r & 63 of word r >> 6, one bitset per layer). The tube
test is precomputed per solve as "viable" words (the tube is free of cells blocked for
the hull, :mod:`hull`), shape (3, m, nx, npsi, nw). Values (the level a state joined
at) are kept as bit planes (m, nx, npsi, nw, n_planes): bit q of the value of a state
is its bit in plane q.

The fixed point follows the frontier: after each level only rows (u, i, k) whose
successor boxes reach a row of W_u that changed are swept. Levels are exact BFS levels
(a state joins at level L + 1 from the states of level <= L), as the dense solver. The
caller drives it one level per call (:func:`advance_level_serial`), so it may stop
once the state it needs joined: every state below that level is final.
"""

from __future__ import annotations

import numpy as np
from numba import prange
from numpy.typing import NDArray

from hil.core.arrays import U64Array
from hil.core.jit import njit, njit_parallel

I32Array = NDArray[np.int32]
U8Array = NDArray[np.uint8]

__all__ = [
    "advance_level_parallel",
    "advance_level_serial",
    "init_layers",
    "shifted",
    "start_levels",
    "successor_run",
]

_ZERO = np.uint64(0)
_ONE = np.uint64(1)
_63 = np.uint64(63)


@njit
def shifted(lo: np.uint64, hi: np.uint64, s: np.uint64) -> np.uint64:
    """Return bits s .. s + 63 of the 128-bit value hi:lo (0 <= s < 64), without a branch."""
    return (lo >> s) | ((hi << _ONE) << (_63 - s))


@njit
def _copy_wraps(W: U64Array, p: int, ip: int, k: int, npsi: int, ph: int) -> None:
    """Copy row (ip, ph + k) of layer p to the padding rows that stand for the same heading."""
    kp = ph + k
    n_kp = W.shape[2]
    other = kp - npsi * (kp // npsi)
    while other < n_kp:
        if other != kp:
            for wp in range(W.shape[3]):
                W[p, ip, other, wp] = W[p, ip, kp, wp]
        other += npsi


@njit
def _set(bits: U64Array, u: int, r: int) -> None:
    bits[u, r >> 6] |= _ONE << np.uint64(r & 63)


_DEBRUIJN = np.uint64(0x03F79D71B4CB0A89)


def _debruijn_table() -> NDArray[np.int64]:
    """Return the de Bruijn bit-index table: entry (2**b * _DEBRUIJN mod 2**64) >> 58 is b."""
    table = np.zeros(64, dtype=np.int64)
    for b in range(64):
        table[((1 << b) * 0x03F79D71B4CB0A89 & (2**64 - 1)) >> 58] = b
    return table


_BIT_OF = _debruijn_table()
"""Index of the single set bit of a word from the top 6 bits of its product with _DEBRUIJN."""


@njit
def _low_index(low: np.uint64) -> int:
    """Return the index of the single set bit of `low` (a de Bruijn multiply, no loop)."""
    return int(_BIT_OF[(low * _DEBRUIJN) >> np.uint64(58)])


@njit
def _row_cells(nx: int, npsi: int) -> tuple[I32Array, I32Array]:
    """Return (i, k) of every row r = i * npsi + k, each shape (nx * npsi,).

    Tables, not r // npsi and r % npsi: an integer division per visited row was a
    measurable share of the sweep.
    """
    row_i = np.empty(nx * npsi, dtype=np.int32)
    row_k = np.empty(nx * npsi, dtype=np.int32)
    for r in range(nx * npsi):
        row_i[r] = r // npsi
        row_k[r] = r % npsi
    return row_i, row_k


@njit
def init_layers(goal: U64Array, W: U64Array, px: int, ph: int, pw: int, chmask: U64Array) -> int:
    """Set every layer of W to the goal words (nx, npsi, nw); return how many rows hold goal.

    Those rows r = i * npsi + k are marked changed in every layer of chmask (m, n_rw).
    """
    m = W.shape[0]
    nx, npsi, nw = goal.shape
    n = 0
    for i in range(nx):
        for k in range(npsi):
            anyb = False
            for w in range(nw):
                if goal[i, k, w] != _ZERO:
                    anyb = True
            if not anyb:
                continue
            n += 1
            r = i * npsi + k
            for p in range(m):
                for w in range(nw):
                    W[p, px + i, ph + k, pw + w] = goal[i, k, w]
                _copy_wraps(W, p, px + i, k, npsi, ph)
                _set(chmask, p, r)
    return n


@njit
def successor_run(
    W: U64Array, u: int, x: int, kp0: int, kp1: int, wp: int, oy0: int, n: int
) -> np.uint64:
    """Return the word of the successor runs of row word wp: n cells from oy0 along y.

    Bit b is set iff cells 64 (wp - pw) + b + oy0 + (0 .. n - 1) win in every row
    (x, kp0 .. kp1) of layer u (1 <= n <= 64). Three words per row are ANDed over the
    heading rows, shifted by oy0 and eroded.
    """
    a = wp + (oy0 >> 6)
    x0 = ~_ZERO
    x1 = ~_ZERO
    x2 = ~_ZERO
    for kk in range(kp0, kp1 + 1):
        x0 &= W[u, x, kk, a]
        x1 &= W[u, x, kk, a + 1]
        x2 &= W[u, x, kk, a + 2]
    s = np.uint64(oy0 & 63)
    lo = shifted(x0, x1, s)
    hi = shifted(x1, x2, s)
    acc = lo
    for d in range(1, n):
        acc &= shifted(lo, hi, np.uint64(d))
    return acc


@njit
def _check(
    cand: np.uint64,
    W: U64Array,
    u: int,
    ip: int,
    kp: int,
    wp: int,
    box: I32Array,
    h0: int,
    h1: int,
    kill: U8Array,
    c: int,
    r: int,
    w: int,
) -> np.uint64:
    """Return the bits of cand whose successor box (ox0, ox1, oy0, oy1) x [h0, h1] lies in W[u].

    The box is read one column ox at a time (all its heading rows at once). The column
    that last emptied the candidates, ox0 + kill[c, u, r, w], is read first (it is the
    likeliest to fail again); when the candidates run out, the emptying column is stored.
    """
    n = box[3] - box[2] + 1
    first = int(kill[c, u, r, w])
    acc = cand & successor_run(W, u, ip + box[0] + first, kp + h0, kp + h1, wp, box[2], n)
    if acc == _ZERO:
        return acc
    for q in range(box[1] - box[0] + 1):
        if q != first:
            acc &= successor_run(W, u, ip + box[0] + q, kp + h0, kp + h1, wp, box[2], n)
            if acc == _ZERO:
                kill[c, u, r, w] = np.uint8(q)
                return acc
    return acc


@njit
def _sweep_layer(
    u: int,
    px: int,
    ph: int,
    pw: int,
    W: U64Array,
    Bset: U64Array,
    viable: U64Array,
    succ: I32Array,
    heading: I32Array,
    umask: U64Array,
    hasA: U64Array,
    hasB: U64Array,
    newA: U64Array,
    newB: U64Array,
    kill: U8Array,
    row_i: I32Array,
    row_k: I32Array,
) -> None:
    """Compute the states of the rows marked in umask[u] that join A_u and B_u next level.

    Writes newA[u, r] and newB[u, r] (m, n_rows, nw) for those rows and marks the rows
    with any in hasA[u] / hasB[u] (cleared first); clears umask[u].
    """
    nw = Bset.shape[2]
    ha0, ha1 = heading[0, u, 0], heading[0, u, 1]
    hb0, hb1 = heading[1, u, 0], heading[1, u, 1]
    for rw in range(umask.shape[1]):
        hasA[u, rw] = _ZERO
        hasB[u, rw] = _ZERO
    for rw in range(umask.shape[1]):
        bits = umask[u, rw]
        umask[u, rw] = _ZERO
        while bits != _ZERO:
            low = bits & (~bits + _ONE)
            bits ^= low
            r = 64 * rw + _low_index(low)
            k = row_k[r]
            i = row_i[r]
            ip = px + i
            kp = ph + k
            box_a = succ[0, k, u]
            box_b = succ[1, k, u]
            any_a = _ZERO
            any_b = _ZERO
            for w in range(nw):
                wp = pw + w
                cur = W[u, ip, kp, wp]
                cand_a = viable[0, u, i, k, w] & ~cur
                got_a = _ZERO
                if cand_a != _ZERO:
                    got_a = _check(cand_a, W, u, ip, kp, wp, box_a, ha0, ha1, kill, 0, r, w)
                # B_u needs the larger class-1 boxes: only states that pass class 0 can.
                cand_b = viable[1, u, i, k, w] & ~Bset[u, r, w] & (got_a | cur)
                got_b = _ZERO
                if cand_b != _ZERO:
                    got_b = _check(cand_b, W, u, ip, kp, wp, box_b, hb0, hb1, kill, 1, r, w)
                newA[u, r, w] = got_a
                newB[u, r, w] = got_b
                any_a |= got_a
                any_b |= got_b
            if any_a != _ZERO:
                hasA[u, rw] |= low
            if any_b != _ZERO:
                hasB[u, rw] |= low


@njit
def _apply_layer(
    p: int,
    level: int,
    npsi: int,
    px: int,
    ph: int,
    pw: int,
    W: U64Array,
    Bset: U64Array,
    planes: U64Array,
    nbr: I32Array,
    nbr_n: I32Array,
    hasA: U64Array,
    hasB: U64Array,
    newA: U64Array,
    newB: U64Array,
    chmask: U64Array,
    row_i: I32Array,
    row_k: I32Array,
) -> int:
    """Join A_p and the neighbours' B_u into layer p at `level`; return the rows changed.

    Marks them in chmask[p]; adds B_p to Bset[p]. Writes only layer p.
    """
    nw = Bset.shape[2]
    nn = nbr_n[p]
    n_changed = 0
    for rw in range(hasA.shape[1]):
        rows = hasA[p, rw]
        for n in range(nn):
            rows |= hasB[nbr[p, n], rw]
        mine_b = hasB[p, rw]
        while mine_b != _ZERO:
            low = mine_b & (~mine_b + _ONE)
            mine_b ^= low
            r = 64 * rw + _low_index(low)
            for w in range(nw):
                Bset[p, r, w] |= newB[p, r, w]
        while rows != _ZERO:
            low = rows & (~rows + _ONE)
            rows ^= low
            b = _low_index(low)
            r = 64 * rw + b
            k = row_k[r]
            i = row_i[r]
            ip = px + i
            kp = ph + k
            changed = False
            a_here = (hasA[p, rw] & low) != _ZERO
            for w in range(nw):
                acc = newA[p, r, w] if a_here else _ZERO
                for n in range(nn):
                    u = nbr[p, n]
                    if (hasB[u, rw] & low) != _ZERO:
                        acc |= newB[u, r, w]
                fresh = acc & ~W[p, ip, kp, pw + w]
                if fresh == _ZERO:
                    continue
                changed = True
                W[p, ip, kp, pw + w] |= fresh
                q = 0
                lv = level
                while lv > 0:
                    if lv & 1:
                        planes[p, i, k, w, q] |= fresh
                    lv >>= 1
                    q += 1
            if changed:
                chmask[p, rw] |= low
                _copy_wraps(W, p, ip, k, npsi, ph)
                n_changed += 1
    return n_changed


@njit
def _activate_layer(
    u: int,
    nx: int,
    npsi: int,
    reach: I32Array,
    h_reach: I32Array,
    chmask: U64Array,
    umask: U64Array,
    row_i: I32Array,
    row_k: I32Array,
) -> int:
    """Mark in umask[u] the rows whose successor boxes reach a row changed in chmask[u].

    Clears chmask[u]; returns how many changed rows there were.
    reach[k, u] = (min ox, max ox) over both classes, h_reach[u] = (min ok, max ok).
    """
    n = 0
    for rw in range(chmask.shape[1]):
        bits = chmask[u, rw]
        chmask[u, rw] = _ZERO
        while bits != _ZERO:
            low = bits & (~bits + _ONE)
            bits ^= low
            r = 64 * rw + _low_index(low)
            n += 1
            k1 = row_k[r]
            i1 = row_i[r]
            for ok in range(h_reach[u, 0], h_reach[u, 1] + 1):
                k0 = k1 - ok
                while k0 < 0:
                    k0 += npsi
                while k0 >= npsi:
                    k0 -= npsi
                lo = max(i1 - reach[k0, u, 1], 0)
                hi = min(i1 - reach[k0, u, 0], nx - 1)
                for i0 in range(lo, hi + 1):
                    _set(umask, u, i0 * npsi + k0)
    return n


@njit
def start_levels(
    W: U64Array,
    planes: U64Array,
    reach: I32Array,
    h_reach: I32Array,
    chmask: U64Array,
    umask: U64Array,
) -> int:
    """Mark the rows the goal's rows activate; return how many goal rows there were.

    On entry W holds the goal in every layer and chmask marks its rows
    (:func:`init_layers`); umask is zero. Then :func:`advance_level_serial` (or its
    parallel twin) joins one level per call.
    """
    m = W.shape[0]
    nx = planes.shape[1]
    npsi = planes.shape[2]
    row_i, row_k = _row_cells(nx, npsi)
    n_changed = 0
    for u in range(m):
        n_changed += _activate_layer(u, nx, npsi, reach, h_reach, chmask, umask, row_i, row_k)
    return n_changed


@njit
def advance_level_serial(
    level: int,
    W: U64Array,
    Bset: U64Array,
    viable: U64Array,
    planes: U64Array,
    pads: I32Array,
    succ: I32Array,
    heading: I32Array,
    reach: I32Array,
    h_reach: I32Array,
    nbr: I32Array,
    nbr_n: I32Array,
    chmask: U64Array,
    umask: U64Array,
    hasA: U64Array,
    hasB: U64Array,
    newA: U64Array,
    newB: U64Array,
    kill: U8Array,
) -> int:
    """Join the states of value `level` + 1 on the calling thread; return the rows changed.

    0 means the fixed point is reached. Between calls every state of value <= `level`
    is final in W and planes and no state of a higher value is set, so a caller may
    stop after any level (the vessel's state joined) and go on later. Shapes: Bset,
    newA, newB (m, n_rows, nw); chmask, umask, hasA, hasB (m, n_rw); kill
    (2, m, n_rows, nw); viable comes from :func:`viable_words`.
    """
    m = W.shape[0]
    nx = planes.shape[1]
    npsi = planes.shape[2]
    px, ph, pw = pads[0], pads[1], pads[2]
    row_i, row_k = _row_cells(nx, npsi)
    for u in range(m):
        _sweep_layer(
            u, px, ph, pw, W, Bset, viable, succ, heading, umask, hasA, hasB,
            newA, newB, kill, row_i, row_k,
        )  # fmt: skip
    n_changed = 0
    for p in range(m):
        n_changed += _apply_layer(
            p, level + 1, npsi, px, ph, pw, W, Bset, planes, nbr, nbr_n, hasA, hasB,
            newA, newB, chmask, row_i, row_k,
        )  # fmt: skip
    if n_changed > 0:
        for u in range(m):
            _activate_layer(u, nx, npsi, reach, h_reach, chmask, umask, row_i, row_k)
    return n_changed


@njit_parallel
def advance_level_parallel(
    level: int,
    W: U64Array,
    Bset: U64Array,
    viable: U64Array,
    planes: U64Array,
    pads: I32Array,
    succ: I32Array,
    heading: I32Array,
    reach: I32Array,
    h_reach: I32Array,
    nbr: I32Array,
    nbr_n: I32Array,
    chmask: U64Array,
    umask: U64Array,
    hasA: U64Array,
    hasB: U64Array,
    newA: U64Array,
    newB: U64Array,
    kill: U8Array,
) -> int:
    """Run one level of :func:`advance_level_serial` with its layers threaded.

    Layers are independent within each phase: a sweep writes only its input's entries,
    a layer's apply writes only that layer, an activation only that layer's marks.
    """
    m = W.shape[0]
    nx = planes.shape[1]
    npsi = planes.shape[2]
    px, ph, pw = pads[0], pads[1], pads[2]
    counts = np.zeros(m, dtype=np.int64)
    row_i, row_k = _row_cells(nx, npsi)
    for u in prange(m):
        _sweep_layer(
            u, px, ph, pw, W, Bset, viable, succ, heading, umask, hasA, hasB,
            newA, newB, kill, row_i, row_k,
        )  # fmt: skip
    for p in prange(m):
        counts[p] = _apply_layer(
            p, level + 1, npsi, px, ph, pw, W, Bset, planes, nbr, nbr_n, hasA, hasB,
            newA, newB, chmask, row_i, row_k,
        )  # fmt: skip
    n_changed = counts.sum()
    if n_changed > 0:
        for u in prange(m):
            _activate_layer(u, nx, npsi, reach, h_reach, chmask, umask, row_i, row_k)
    return int(n_changed)
