"""The safety game's greatest fixed point in the bit-plane layout: where the vessel can stay.

Same game as the reach-avoid solve (:mod:`planes_kernel`): a state is a cell with the
reference in force p; at each decision the vessel holds p (class 0) or changes to a
lattice neighbour u in N(p) (class 1). Without a target, the largest set S it can stay
in forever (hull off the grown obstacles, inside the walls, every tube free) is

    S_p = (V0_p and Pre0(S_p))  or  OR over u in N(p) of (V1_u and Pre1(S_u)),

Vc_u the states whose tube is free for u in class c, Pre_c(S_u) those whose class-c
successor box (cells and heading range) lies in S_u. It is found by iterating from
S0_p = V0_p or OR_u V1_u, which holds S and contains its own image, so the iterates fall
to S exactly (Knaster-Tarski on a finite lattice).

Work follows the removals: the box test of a state changes only when a cell of its box
left S at the last iteration, so each iteration tests, per (input, heading, class), only
the x band whose boxes reach a row that changed (the reach kernel's banding, mirrored),
and only states still holding that option (A_u = V0_u and Pre0, B_u = V1_u and Pre1 only
lose states). Then each S_p is recomputed on the rows where A_p or some B_u, u in N(p),
lost a state.

Layout (:mod:`planes_kernel`'s, x contiguous): ``St`` (m, npsi, nw + 2 pw, nx + 2 px)
with zero padding; ``At``, ``Bt`` (m, npsi, nw, nx); ``Vt`` (3, m, npsi, nw, nx) (the
viable words, :mod:`viable`); ``ch``, ``band_a``, ``band_b`` (m, npsi, 2) x ranges
[lo, hi] of the rows that lost bits at the last iteration (lo > hi: none).
"""

from __future__ import annotations

import numpy as np
from numba import prange
from numpy.typing import NDArray

from hil.controllers.symbolic.box_test import (
    box_scratch,
    box_test,
    changed_band,
    split_box_scratch,
)
from hil.core.arrays import U64Array
from hil.core.borrow import borrowed
from hil.core.jit import njit, njit_parallel

I32Array = NDArray[np.int32]

__all__ = ["init_safety_state", "safety_iterate_parallel", "safety_iterate_serial"]

_ZERO = np.uint64(0)


@njit
def init_safety_state(
    Vt: U64Array,
    neighbours: I32Array,
    n_neighbours: I32Array,
    St: U64Array,
    At: U64Array,
    Bt: U64Array,
    ch: I32Array,
    px: int,
    pw: int,
) -> None:
    """Set S0_p = V0_p or OR over u in N(p) of V1_u, A = V0, B = V1; every row "changed"."""
    _, m, npsi, nw, nx = Vt.shape
    for u in range(m):
        for k in range(npsi):
            ch[u, k, 0] = 0
            ch[u, k, 1] = nx - 1
            for w in range(nw):
                a = At[u, k, w]
                b = Bt[u, k, w]
                v0 = Vt[0, u, k, w]
                v1 = Vt[1, u, k, w]
                for i in range(nx):
                    a[i] = v0[i]
                    b[i] = v1[i]
    for p in range(m):
        for k in range(npsi):
            for w in range(nw):
                s = St[p, k, pw + w, px : px + nx]
                v0 = Vt[0, p, k, w]
                for i in range(nx):
                    s[i] = v0[i]
                for c in range(n_neighbours[p]):
                    v1 = Vt[1, neighbours[p, c], k, w]
                    for i in range(nx):
                        s[i] |= v1[i]


@njit
def _test_input(
    u: int,
    St: U64Array,
    At: U64Array,
    Bt: U64Array,
    band_a: I32Array,
    band_b: I32Array,
    ch: I32Array,
    succ: I32Array,
    heading: I32Array,
    px: int,
    pw: int,
    words: U64Array,
) -> None:
    """Remove from A_u, B_u the states whose box left S_u; set their bands of removed rows.

    Reads St[u] and ch[u], writes only input u's entries (inputs may run side by side).
    words: :func:`box_test.box_scratch`, borrowed.
    """
    npsi = St.shape[1]
    nw = At.shape[2]
    nx = At.shape[3]
    H, L, R, out, _ = split_box_scratch(words, nw, St.shape[3], nx)
    for k0 in range(npsi):
        for c in range(2):
            band = band_a if c == 0 else band_b
            X = At if c == 0 else Bt
            band[u, k0, 0] = nx
            band[u, k0, 1] = -1
            h0 = heading[c, u, 0]
            h1 = heading[c, u, 1]
            box = succ[c, k0, u]
            lo, hi = changed_band(ch, u, k0, h0, h1, box, nx)
            first = nx
            last = -1
            for i in range(lo, hi + 1):
                anyx = _ZERO
                for w in range(nw):
                    anyx |= X[u, k0, w, i]
                if anyx != _ZERO:
                    first = min(first, i)
                    last = i
            if first > last:
                continue
            lo = first
            hi = last
            box_test(St, u, k0, h0, h1, box, lo, hi, px, pw, H, L, R, out)
            first = nx
            last = -1
            for i in range(lo, hi + 1):
                lost = _ZERO
                for w in range(nw):
                    x = X[u, k0, w, i]
                    kept = x & out[w, i]
                    lost |= x & ~kept
                    X[u, k0, w, i] = kept
                if lost != _ZERO:
                    first = min(first, i)
                    last = i
            band[u, k0, 0] = first
            band[u, k0, 1] = last


@njit
def _update_heading(
    k: int,
    St: U64Array,
    At: U64Array,
    Bt: U64Array,
    band_a: I32Array,
    band_b: I32Array,
    ch: I32Array,
    neighbours: I32Array,
    n_neighbours: I32Array,
    px: int,
    pw: int,
    scratch: U64Array,
) -> int:
    """S_p &= A_p or OR of B_u (u in N(p)) at heading k, on rows some option lost; return rows.

    Writes ch[:, k] and heading k of St only. scratch (2, nx): the kept words and the lost
    rows of one x band, borrowed.
    """
    m = St.shape[0]
    nw = At.shape[2]
    nx = At.shape[3]
    keep = scratch[0]
    rows = scratch[1]
    n_changed = 0
    for p in range(m):
        lo = band_a[p, k, 0]
        hi = band_a[p, k, 1]
        for c in range(n_neighbours[p]):
            u = neighbours[p, c]
            if band_b[u, k, 0] <= band_b[u, k, 1]:
                lo = min(lo, band_b[u, k, 0])
                hi = max(hi, band_b[u, k, 1])
        ch[p, k, 0] = nx
        ch[p, k, 1] = -1
        if lo > hi:
            continue
        nb = hi + 1 - lo
        r = rows[:nb]
        for w in range(nw):
            # Each option's row at a time, contiguous over x (an element at a time, the
            # 27 options' words of one x row lie in 27 cache lines: 2.5x slower).
            kw = keep[:nb]
            a = At[p, k, w, lo : hi + 1]
            for t in range(nb):
                kw[t] = a[t]
            for c in range(n_neighbours[p]):
                b = Bt[neighbours[p, c], k, w, lo : hi + 1]
                for t in range(nb):
                    kw[t] |= b[t]
            sw = St[p, k, pw + w, px + lo : px + hi + 1]
            for t in range(nb):
                lost = sw[t] & ~kw[t]
                r[t] = lost if w == 0 else r[t] | lost
                sw[t] &= kw[t]
        first = nx
        last = -1
        for t in range(nb):
            if r[t] != _ZERO:
                n_changed += 1
                first = min(first, lo + t)
                last = lo + t
        ch[p, k, 0] = first
        ch[p, k, 1] = last
    return n_changed


@njit
def safety_iterate_serial(
    St: U64Array,
    At: U64Array,
    Bt: U64Array,
    band_a: I32Array,
    band_b: I32Array,
    ch: I32Array,
    succ: I32Array,
    heading: I32Array,
    neighbours: I32Array,
    n_neighbours: I32Array,
    pads: I32Array,
    max_iterations: int,
) -> int:
    """Iterate to the greatest fixed point on the calling thread; return the iterations.

    -1 when `max_iterations` passed without reaching it (St then still holds S, and more).
    """
    # Borrowed views: the caller holds the arrays for the whole call (hil.core.borrow).
    St, At, Bt, ch, pads = borrowed(St), borrowed(At), borrowed(Bt), borrowed(ch), borrowed(pads)
    band_a, band_b = borrowed(band_a), borrowed(band_b)
    succ, heading = borrowed(succ), borrowed(heading)
    neighbours, n_neighbours = borrowed(neighbours), borrowed(n_neighbours)
    m, npsi, nw, nx = At.shape
    px, pw = pads[0], pads[2]
    words = box_scratch(nw, St.shape[3], nx)
    keep_rows = np.empty((2, nx), dtype=np.uint64)
    for it in range(max_iterations):
        for u in range(m):
            _test_input(u, St, At, Bt, band_a, band_b, ch, succ, heading, px, pw,
                        borrowed(words))
        n = 0
        for k in range(npsi):
            n += _update_heading(
                k, St, At, Bt, band_a, band_b, ch, neighbours, n_neighbours, px, pw,
                borrowed(keep_rows),
            )
        if n == 0:
            return it + 1
    return -1


@njit_parallel
def safety_iterate_parallel(
    St: U64Array,
    At: U64Array,
    Bt: U64Array,
    band_a: I32Array,
    band_b: I32Array,
    ch: I32Array,
    succ: I32Array,
    heading: I32Array,
    neighbours: I32Array,
    n_neighbours: I32Array,
    pads: I32Array,
    max_iterations: int,
) -> int:
    """:func:`safety_iterate_serial` with the inputs' tests and the headings' updates threaded."""
    # Borrowed views: the caller holds the arrays for the whole call (hil.core.borrow).
    St, At, Bt, ch, pads = borrowed(St), borrowed(At), borrowed(Bt), borrowed(ch), borrowed(pads)
    band_a, band_b = borrowed(band_a), borrowed(band_b)
    succ, heading = borrowed(succ), borrowed(heading)
    neighbours, n_neighbours = borrowed(neighbours), borrowed(n_neighbours)
    m, npsi, nw, nx = At.shape
    px, pw = pads[0], pads[2]
    counts = np.zeros(npsi, dtype=np.int64)
    for it in range(max_iterations):
        for u in prange(m):
            words = box_scratch(nw, St.shape[3], nx)
            _test_input(u, St, At, Bt, band_a, band_b, ch, succ, heading, px, pw,
                        borrowed(words))
        for k in prange(npsi):
            keep_rows = np.empty((2, nx), dtype=np.uint64)
            counts[k] = _update_heading(
                k, St, At, Bt, band_a, band_b, ch, neighbours, n_neighbours, px, pw,
                borrowed(keep_rows),
            )
        if counts.sum() == 0:
            return it + 1
    return -1
