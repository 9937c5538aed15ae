"""Compiled frontier sweeps of the reach-avoid game over (cell, current reference).

The game's state is a grid cell plus the reference p the low level is tracking (the
previous command); from (cell, p) the controller may command any u within one grid step
per axis of p (:class:`~hil.controllers.symbolic.lattice.InputLattice`). Holding p is
budgeted by the class-0 tables, a change by the class-1 tables, so with

    A_u = Pre0_u(W_u),   B_u = Pre1_u(W_u)   (tube free, successor box inside W_u)

the winning sets of the layers satisfy  W_p = A_p  union  (union over u in N(p) of B_u).
Each level computes A_u and B_u once per input from the layer W_u they need (not once
per (p, u) pair), then ORs B_u into the up to 26 neighbouring layers.

Layout: W has shape (3, nx + 2 px, npsi + 2 ph, m, nw + 2 pw) (uint64): bit b of word
pw + w in row (px + i, ph + k) of layer p of W[0] is cell (i, j = 64 w + b, k); W[1] and
W[2] are its erosions along y (cells j .. j + 1, j .. j + 3 all win), so that a run of up
to 8 successor cells along y is two reads. The layers are the inner axis so that the up
to 26 layers a B_u joins share cache lines. Padding rows stay
zero (not winning: outside the grid), heading rows k < 0 or k >= npsi copy the rows they
wrap to. A successor box [ox0, ox1] x [oy0, oy1] x [ok0, ok1] of 64 cells at once is the
AND over rows (i + ox, k + ok) of their y-runs shifted by oy0. The tube test is
precomputed per solve as "viable" words (the tube is free of cells blocked for the hull,
:mod:`hull`), shape (3, nx, npsi, m, nw). Values (the level a state joined at) are kept as bit planes
(nx, npsi, m, nw, n_planes): bit q of the value of a state is its bit in plane q.

The fixed point follows the frontier: after each level only rows (u, i, k) whose
successor boxes reach a row of W_u that changed are swept. Levels are exact BFS levels
(a state joins at level L + 1 from the states of level <= L), as the dense solver.
"""

from __future__ import annotations

import numpy as np
from numba import prange
from numpy.typing import NDArray

from hil.core.jit import njit, njit_parallel

U64Array = NDArray[np.uint64]
I32Array = NDArray[np.int32]
U8Array = NDArray[np.uint8]

__all__ = [
    "erode_free",
    "fixed_point_parallel",
    "fixed_point_serial",
    "init_layers",
    "viable_words",
]

_ZERO = np.uint64(0)
_ONE = np.uint64(1)
_63 = np.uint64(63)


@njit
def _shifted(lo: np.uint64, hi: np.uint64, s: np.uint64) -> np.uint64:
    """Return bits s .. s + 63 of the 128-bit value hi:lo (0 <= s < 64), without a branch."""
    return (lo >> s) | ((hi << _ONE) << (_63 - s))


@njit
def erode_free(F0: U64Array, out: U64Array) -> None:
    """Fill out (layers, rows, words) from F0 (rows, words): y-runs of free cells.

    Layer h has bit j set iff bits j .. j + h of F0 all are (F0's last word pads).
    """
    n_rows, n_w = F0.shape
    for r in range(n_rows):
        for w in range(n_w):
            out[0, r, w] = F0[r, w]
    for h in range(1, out.shape[0]):
        q = h >> 6
        s = np.uint64(h & 63)
        for r in range(n_rows):
            for w in range(n_w):
                if w + q + 1 < n_w:
                    out[h, r, w] = out[h - 1, r, w] & _shifted(F0[r, w + q], F0[r, w + q + 1], s)
                elif w + q < n_w:
                    out[h, r, w] = out[h - 1, r, w] & (F0[r, w + q] >> s)
                else:
                    out[h, r, w] = _ZERO


@njit
def viable_words(
    Fe: U64Array,
    cls: int,
    k: int,
    u: int,
    tube_x0: I32Array,
    tube_n: I32Array,
    tube_y: I32Array,
    px: int,
    pw: int,
    out: U64Array,
) -> None:
    """Fill out[cls, :, k, u, :]: cells whose tube (class cls, input u, heading k) is free.

    Fe holds the free cells eroded along y, shape (layers, nx + 2 px, nw + 2 pw).
    """
    nx = out.shape[1]
    nw = out.shape[4]
    x0 = tube_x0[cls, k, u]
    for i in range(nx):
        ip = px + i
        for w in range(nw):
            wp = pw + w
            acc = ~_ZERO
            for c in range(tube_n[cls, k, u]):
                y0 = tube_y[cls, k, u, c, 0]
                h = tube_y[cls, k, u, c, 1] - y0
                a = wp + (y0 >> 6)
                s = np.uint64(y0 & 63)
                x = ip + x0 + c
                acc &= _shifted(Fe[h, x, a], Fe[h, x, a + 1], s)
                if acc == _ZERO:
                    break
            out[cls, i, k, u, w] = acc


@njit
def _copy_wraps(W: U64Array, p: int, ip: int, k: int, npsi: int, ph: int) -> None:
    """Copy row (ip, ph + k) of layer p to the padding rows that stand for the same heading."""
    kp = ph + k
    n_kp = W.shape[2]
    other = kp - npsi * (kp // npsi)
    while other < n_kp:
        if other != kp:
            for e in range(W.shape[0]):
                for wp in range(W.shape[4]):
                    W[e, ip, other, p, wp] = W[e, ip, kp, p, wp]
        other += npsi


@njit
def _erode(W: U64Array, p: int, ip: int, kp: int) -> None:
    """Recompute the y-erosions of row (ip, kp) of layer p: W[1] pairs, W[2] quadruples.

    Bit j of W[1] is set iff cells j, j + 1 win; of W[2] iff cells j .. j + 3 win.
    """
    n_w = W.shape[4]
    for wp in range(n_w - 1):
        W[1, ip, kp, p, wp] = W[0, ip, kp, p, wp] & _shifted(
            W[0, ip, kp, p, wp], W[0, ip, kp, p, wp + 1], _ONE
        )
    W[1, ip, kp, p, n_w - 1] = _ZERO
    for wp in range(n_w - 1):
        W[2, ip, kp, p, wp] = W[1, ip, kp, p, wp] & _shifted(
            W[1, ip, kp, p, wp], W[1, ip, kp, p, wp + 1], np.uint64(2)
        )
    W[2, ip, kp, p, n_w - 1] = _ZERO


@njit
def init_layers(
    goal: U64Array, W: U64Array, px: int, ph: int, pw: int, chmask: U64Array, rows: I32Array
) -> int:
    """Set every layer of W to the goal words (nx, npsi, nw); return the rows listed.

    Those rows are marked changed in every layer (chmask) and listed in `rows`.
    """
    m = W.shape[3]
    nx, npsi, nw = goal.shape
    n = 0
    for i in range(nx):
        for k in range(npsi):
            anyb = False
            for w in range(nw):
                if goal[i, k, w] != _ZERO:
                    anyb = True
            for p in range(m):
                for w in range(nw):
                    W[0, px + i, ph + k, p, pw + w] = goal[i, k, w]
                _erode(W, p, px + i, ph + k)
                _copy_wraps(W, p, px + i, k, npsi, ph)
            if anyb:
                r = i * npsi + k
                rows[n] = r
                n += 1
                for p in range(m):
                    chmask[r, p >> 6] |= _ONE << np.uint64(p & 63)
    return n


@njit
def _run(W: U64Array, x: int, kk: int, u: int, wp: int, oy0: int, oy1: int) -> np.uint64:
    """Return the words whose cells j + oy0 .. j + oy1 all win in row (x, kk) of layer u.

    Two reads of the erosions cover a run of up to 8 cells; longer runs take more.
    """
    n = oy1 - oy0 + 1
    if n == 1:
        a = wp + (oy0 >> 6)
        return _shifted(W[0, x, kk, u, a], W[0, x, kk, u, a + 1], np.uint64(oy0 & 63))
    e = 1 if n <= 4 else 2
    span = 2 if e == 1 else 4
    acc = ~_ZERO
    oy = oy0
    while True:
        start = min(oy, oy1 - span + 1)
        a = wp + (start >> 6)
        acc &= _shifted(W[e, x, kk, u, a], W[e, x, kk, u, a + 1], np.uint64(start & 63))
        if start + span - 1 >= oy1:
            return acc
        oy = start + span


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
) -> np.uint64:
    """Return the bits of cand whose successor box (ox0, ox1, oy0, oy1) x [h0, h1] lies in W[u]."""
    acc = cand
    for ox in range(box[0], box[1] + 1):
        for ok in range(h0, h1 + 1):
            acc &= _run(W, ip + ox, kp + ok, u, wp, box[2], box[3])
            if acc == _ZERO:
                return acc
    return acc


@njit
def _bit(mask: U64Array, r: int, u: int) -> bool:
    return (mask[r, u >> 6] >> np.uint64(u & 63)) & _ONE != _ZERO


@njit
def _sweep_row(
    r: int,
    npsi: int,
    nw: int,
    px: int,
    ph: int,
    pw: int,
    W: U64Array,
    Bset: U64Array,
    viable: U64Array,
    succ: I32Array,
    heading: I32Array,
    nbr: I32Array,
    nbr_n: I32Array,
    umask: U64Array,
    newA: U64Array,
    newB: U64Array,
) -> None:
    """Compute the states of row r = i * npsi + k that join A_u and B_u next level.

    For each input u marked in umask[r]: newA[r, u] and newB[r, u].
    """
    k = r % npsi
    i = r // npsi
    ip = px + i
    kp = ph + k
    for mw in range(umask.shape[1]):
        bits = umask[r, mw]
        while bits != _ZERO:
            low = bits & (~bits + _ONE)
            b = 0
            t = low
            while t > _ONE:
                t >>= _ONE
                b += 1
            bits ^= low
            u = 64 * mw + b
            for w in range(nw):
                wp = pw + w
                cur = W[0, ip, kp, u, wp]
                cand_a = viable[0, i, k, u, w] & ~cur
                got_a = _ZERO
                if cand_a != _ZERO:
                    got_a = _check(
                        cand_a, W, u, ip, kp, wp, succ[0, k, u], heading[0, u, 0], heading[0, u, 1]
                    )
                # B_u needs the larger class-1 boxes: only states that pass class 0 can,
                # and only states some neighbouring layer still lacks matter.
                cand_b = viable[1, i, k, u, w] & ~Bset[i, k, u, w] & (got_a | cur)
                if cand_b != _ZERO:
                    everywhere = ~_ZERO
                    for n in range(nbr_n[u]):
                        everywhere &= W[0, ip, kp, nbr[u, n], wp]
                    cand_b &= ~everywhere
                got_b = _ZERO
                if cand_b != _ZERO:
                    got_b = _check(
                        cand_b, W, u, ip, kp, wp, succ[1, k, u], heading[1, u, 0], heading[1, u, 1]
                    )
                newA[r, u, w] = got_a
                newB[r, u, w] = got_b


@njit
def _join(
    p: int,
    i: int,
    k: int,
    w: int,
    bits: np.uint64,
    level: int,
    px: int,
    ph: int,
    pw: int,
    W: U64Array,
    planes: U64Array,
) -> bool:
    """Add `bits` to layer p at `level`; return True when a state joined."""
    fresh = bits & ~W[0, px + i, ph + k, p, pw + w]
    if fresh == _ZERO:
        return False
    W[0, px + i, ph + k, p, pw + w] |= fresh
    q = 0
    lv = level
    while lv > 0:
        if lv & 1:
            planes[i, k, p, w, q] |= fresh
        lv >>= 1
        q += 1
    return True


@njit
def _apply_row(
    r: int,
    level: int,
    npsi: int,
    nw: int,
    px: int,
    ph: int,
    pw: int,
    W: U64Array,
    Bset: U64Array,
    planes: U64Array,
    nbr: I32Array,
    nbr_n: I32Array,
    umask: U64Array,
    newA: U64Array,
    newB: U64Array,
    chmask: U64Array,
) -> None:
    """Merge row r's new states into the layers; mark changed layers in chmask[r].

    Clears umask[r]. Touches only row r (and its heading copies).
    """
    k = r % npsi
    i = r // npsi
    for mw in range(umask.shape[1]):
        bits = umask[r, mw]
        umask[r, mw] = _ZERO
        while bits != _ZERO:
            low = bits & (~bits + _ONE)
            b = 0
            t = low
            while t > _ONE:
                t >>= _ONE
                b += 1
            bits ^= low
            u = 64 * mw + b
            for w in range(nw):
                got = newA[r, u, w]
                if got != _ZERO and _join(u, i, k, w, got, level, px, ph, pw, W, planes):
                    chmask[r, u >> 6] |= _ONE << np.uint64(u & 63)
                got = newB[r, u, w]
                if got != _ZERO:
                    Bset[i, k, u, w] |= got
                    for n in range(nbr_n[u]):
                        p = nbr[u, n]
                        if _join(p, i, k, w, got, level, px, ph, pw, W, planes):
                            chmask[r, p >> 6] |= _ONE << np.uint64(p & 63)
    for mw in range(chmask.shape[1]):
        bits = chmask[r, mw]
        while bits != _ZERO:
            low = bits & (~bits + _ONE)
            b = 0
            t = low
            while t > _ONE:
                t >>= _ONE
                b += 1
            bits ^= low
            p = 64 * mw + b
            _erode(W, p, px + i, ph + k)
            _copy_wraps(W, p, px + i, k, npsi, ph)


@njit
def _activate(
    changed_rows: I32Array,
    n_changed: int,
    nx: int,
    npsi: int,
    reach: I32Array,
    h_reach: I32Array,
    chmask: U64Array,
    umask: U64Array,
    row_flag: U8Array,
    active_rows: I32Array,
) -> int:
    """Mark the rows (i0, k0) and inputs u to sweep next; return how many rows.

    A row is marked for u (umask) when u's successor boxes reach a row where W_u
    changed (chmask, cleared here); the rows are listed in active_rows.

    reach[k, u] = (min ox, max ox) over both classes, h_reach[u] = (min ok, max ok).
    """
    n = 0
    for c in range(n_changed):
        r = changed_rows[c]
        k1 = r % npsi
        i1 = r // npsi
        for mw in range(chmask.shape[1]):
            bits = chmask[r, mw]
            chmask[r, mw] = _ZERO
            while bits != _ZERO:
                low = bits & (~bits + _ONE)
                b = 0
                t = low
                while t > _ONE:
                    t >>= _ONE
                    b += 1
                bits ^= low
                u = 64 * mw + b
                for ok in range(h_reach[u, 0], h_reach[u, 1] + 1):
                    k0 = k1 - ok
                    while k0 < 0:
                        k0 += npsi
                    while k0 >= npsi:
                        k0 -= npsi
                    lo = max(i1 - reach[k0, u, 1], 0)
                    hi = min(i1 - reach[k0, u, 0], nx - 1)
                    for i0 in range(lo, hi + 1):
                        r0 = i0 * npsi + k0
                        umask[r0, mw] |= low
                        if row_flag[r0] == 0:
                            row_flag[r0] = 1
                            active_rows[n] = r0
                            n += 1
    for a in range(n):
        row_flag[active_rows[a]] = 0
    return n


@njit
def _changed_rows(
    active_rows: I32Array, n_active: int, chmask: U64Array, changed_rows: I32Array
) -> int:
    n = 0
    for a in range(n_active):
        r = active_rows[a]
        for mw in range(chmask.shape[1]):
            if chmask[r, mw] != _ZERO:
                changed_rows[n] = r
                n += 1
                break
    return n


@njit
def fixed_point_serial(
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
    changed_rows: I32Array,
    n_changed: int,
    chmask: U64Array,
    umask: U64Array,
    row_flag: U8Array,
    active_rows: I32Array,
    newA: U64Array,
    newB: U64Array,
) -> int:
    """Run the fixed point on the calling thread; return the number of levels (-1: too many).

    On entry W holds the goal in every layer and chmask marks its rows
    (:func:`init_layers`), Bset, planes and umask are zero, viable comes from
    :func:`viable_words`. Row arrays are indexed r = i * npsi + k.
    """
    nx, npsi, _, nw = Bset.shape
    px, ph, pw = pads[0], pads[1], pads[2]
    max_level = (1 << planes.shape[4]) - 1
    level = 0
    n_active = _activate(
        changed_rows, n_changed, nx, npsi, reach, h_reach, chmask, umask, row_flag, active_rows
    )
    while n_active > 0:
        if level + 1 > max_level:
            return -1
        for a in range(n_active):
            _sweep_row(
                active_rows[a],
                npsi,
                nw,
                px,
                ph,
                pw,
                W,
                Bset,
                viable,
                succ,
                heading,
                nbr,
                nbr_n,
                umask,
                newA,
                newB,
            )
        for a in range(n_active):
            _apply_row(
                active_rows[a],
                level + 1,
                npsi,
                nw,
                px,
                ph,
                pw,
                W,
                Bset,
                planes,
                nbr,
                nbr_n,
                umask,
                newA,
                newB,
                chmask,
            )
        n_changed = _changed_rows(active_rows, n_active, chmask, changed_rows)
        if n_changed == 0:
            break
        level += 1
        n_active = _activate(
            changed_rows,
            n_changed,
            nx,
            npsi,
            reach,
            h_reach,
            chmask,
            umask,
            row_flag,
            active_rows,
        )
    return level


@njit_parallel
def fixed_point_parallel(
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
    changed_rows: I32Array,
    n_changed: int,
    chmask: U64Array,
    umask: U64Array,
    row_flag: U8Array,
    active_rows: I32Array,
    newA: U64Array,
    newB: U64Array,
) -> int:
    """Run the fixed point of :func:`fixed_point_serial` with each level's rows threaded.

    Rows are independent: a row's joins touch only that row and its heading copies.
    """
    nx, npsi, _, nw = Bset.shape
    px, ph, pw = pads[0], pads[1], pads[2]
    max_level = (1 << planes.shape[4]) - 1
    level = 0
    n_active = _activate(
        changed_rows, n_changed, nx, npsi, reach, h_reach, chmask, umask, row_flag, active_rows
    )
    while n_active > 0:
        if level + 1 > max_level:
            return -1
        for a in prange(n_active):
            _sweep_row(
                active_rows[a],
                npsi,
                nw,
                px,
                ph,
                pw,
                W,
                Bset,
                viable,
                succ,
                heading,
                nbr,
                nbr_n,
                umask,
                newA,
                newB,
            )
        for a in prange(n_active):
            _apply_row(
                active_rows[a],
                level + 1,
                npsi,
                nw,
                px,
                ph,
                pw,
                W,
                Bset,
                planes,
                nbr,
                nbr_n,
                umask,
                newA,
                newB,
                chmask,
            )
        n_changed = _changed_rows(active_rows, n_active, chmask, changed_rows)
        if n_changed == 0:
            break
        level += 1
        n_active = _activate(
            changed_rows,
            n_changed,
            nx,
            npsi,
            reach,
            h_reach,
            chmask,
            umask,
            row_flag,
            active_rows,
        )
    return level
