"""The successor-box test of the bit-plane kernels, one x band of one (input, heading) slab.

Shared by the reach-avoid fixed point (:mod:`planes_kernel`) and the safety set
(:mod:`safety_kernel`): whether every cell of a state's successor box lies in a set, for
the states of a band of x rows, tested separably (heading rows, then y, then x), and the
band of rows whose boxes reach the rows changed at the last level.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.frontier_kernel import shifted
from hil.core.arrays import U64Array
from hil.core.jit import njit

I32Array = NDArray[np.int32]

__all__ = ["box_test", "changed_band", "row_ends"]

_ZERO = np.uint64(0)


@njit
def box_test(
    Wt: U64Array,
    u: int,
    k0: int,
    h0: int,
    h1: int,
    box: I32Array,
    lo: int,
    hi: int,
    px: int,
    pw: int,
    H: U64Array,
    L: U64Array,
    R: U64Array,
    out: U64Array,
) -> None:
    """Fill out[w, i], i in [lo, hi]: whether the successor box of (i, 64 w + b, k0) is in Wt[u].

    H (nw + 2, nx + 2 px), L, R (nw, nx + 2 px) and out (nw, nx) are scratch / result.
    Separable: heading AND, then y shift and erosion, then the x window. Loops run over
    slice views from index 0 (a provably non-negative index lets LLVM vectorize them).
    """
    npsi = Wt.shape[1]
    nw = out.shape[0]
    ox0, ox1, oy0, oy1 = box[0], box[1], box[2], box[3]
    xa = px + lo + ox0
    xb = px + hi + ox1 + 1
    nxh = xb - xa
    a = pw + (oy0 >> 6)
    s = np.uint64(oy0 & 63)
    k = (k0 + h0) % npsi
    for q in range(nw + 2):
        dst = H[q, :nxh]
        if a + q < pw or a + q >= pw + nw:  # a padding word: zero in every heading row
            for x in range(nxh):
                dst[x] = _ZERO
            continue
        src = Wt[u, k, a + q, xa:xb]
        for x in range(nxh):
            dst[x] = src[x]
    for ok in range(h0 + 1, h1 + 1):
        k = (k0 + ok) % npsi
        for q in range(nw + 2):
            if a + q < pw or a + q >= pw + nw:
                continue
            src = Wt[u, k, a + q, xa:xb]
            dst = H[q, :nxh]
            for x in range(nxh):
                dst[x] &= src[x]
    for w in range(nw):
        h_0 = H[w, :nxh]
        h_1 = H[w + 1, :nxh]
        h_2 = H[w + 2, :nxh]
        lw = L[w, :nxh]
        rw = R[w, :nxh]
        for x in range(nxh):
            lw[x] = shifted(h_0[x], h_1[x], s)
            rw[x] = shifted(h_1[x], h_2[x], s)
    n = oy1 - oy0 + 1
    span = 1
    while 2 * span <= n:
        d = np.uint64(span)
        for w in range(nw):
            lw = L[w, :nxh]
            rw = R[w, :nxh]
            for x in range(nxh):
                lv = lw[x]
                rv = rw[x]
                lw[x] = lv & shifted(lv, rv, d)
                rw[x] = rv & (rv >> d)
        span *= 2
    if n > span:
        d = np.uint64(n - span)
        for w in range(nw):
            lw = L[w, :nxh]
            rw = R[w, :nxh]
            for x in range(nxh):
                lw[x] = lw[x] & shifted(lw[x], rw[x], d)
    # The x window by doubling: E_2s(x) = E_s(x) and E_s(x + s), ping-pong in L and R.
    nb = hi + 1 - lo
    nbx = ox1 - ox0 + 1
    for w in range(nw):
        src_e = L[w]
        dst_e = R[w]
        span = 1
        valid = nxh
        while 2 * span <= nbx:
            valid -= span
            e0 = src_e[:valid]
            e1 = src_e[span : span + valid]
            d = dst_e[:valid]
            for x in range(valid):
                d[x] = e0[x] & e1[x]
            src_e, dst_e = dst_e, src_e
            span *= 2
        ow = out[w, lo : hi + 1]
        e0 = src_e[:nb]
        e1 = src_e[nbx - span : nbx - span + nb]
        for i in range(nb):
            ow[i] = e0[i] & e1[i]


@njit
def changed_band(
    ch: I32Array, u: int, k0: int, h0: int, h1: int, box: I32Array, nx: int
) -> tuple[int, int]:
    """Return the x rows [lo, hi] of heading k0 whose box reaches a changed row of layer u.

    The box (ox0, ox1, ...) spans headings k0 + h0 .. k0 + h1; ch (m, npsi, 2) holds each
    heading's changed rows; lo > hi: none. A box test changes only where a cell of its box
    changed, so only these rows need it.
    """
    npsi = ch.shape[1]
    cl = nx
    chh = -1
    for ok in range(h0, h1 + 1):
        k = (k0 + ok) % npsi
        cl = min(cl, ch[u, k, 0])
        chh = max(chh, ch[u, k, 1])
    if cl > chh:
        return nx, -1
    return max(cl - box[1], 0), min(chh - box[0], nx - 1)


@njit
def row_ends(rows: U64Array, lo: int, n: int, nx: int) -> tuple[int, int]:
    """Return lo + the first and last index of a nonzero entry of rows[:n]; (nx, -1): none."""
    first = -1
    for i in range(n):
        if rows[i] != _ZERO:
            first = i
            break
    if first < 0:
        return nx, -1
    last = first
    for i in range(n - 1, first, -1):
        if rows[i] != _ZERO:
            last = i
            break
    return lo + first, lo + last
