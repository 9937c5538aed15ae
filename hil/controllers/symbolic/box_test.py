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
from hil.core.jit import njit, njit_inline

I32Array = NDArray[np.int32]

__all__ = ["box_scratch", "box_test", "changed_band", "row_ends", "split_box_scratch"]

_ZERO = np.uint64(0)
_ONE = np.uint64(1)


@njit
def box_scratch(nw: int, xp: int, nx: int) -> U64Array:
    """Return one flat scratch for box_test on words of xp padded (nx grid) x rows.

    :func:`split_box_scratch` cuts it into box_test's H, L, R, its out and a row of words.
    One array, so that a kernel hands it on with one :func:`~hil.core.borrow.borrowed`.
    """
    return np.empty((nw + 2) * xp + 2 * nw * xp + nw * nx + nx, dtype=np.uint64)


@njit_inline
def split_box_scratch(
    words: U64Array, nw: int, xp: int, nx: int
) -> tuple[U64Array, U64Array, U64Array, U64Array, U64Array]:
    """Return the views (H ((nw + 2) xp), L, R (nw xp), out (nw, nx), row (nx)) of `words`."""
    a = (nw + 2) * xp
    b = a + nw * xp
    c = b + nw * xp
    d = c + nw * nx
    return words[:a], words[a:b], words[b:c], words[c:d].reshape((nw, nx)), words[d : d + nx]


@njit_inline
def box_test(
    Wt: U64Array, u: int, k0: int, h0: int, h1: int, box: I32Array, lo: int, hi: int,
    px: int, pw: int, H: U64Array, L: U64Array, R: U64Array, out: U64Array,
) -> None:  # fmt: skip
    """Fill out[w, i], i in [lo, hi]: whether the successor box of (i, 64 w + b, k0) is in Wt[u].

    Wt (m, npsi, nw + 2 pw, nx + 2 px) as :mod:`planes_kernel` lays it out; box (ox0,
    ox1, oy0, oy1) the x and y offsets, h0 .. h1 the headings of the box; H, L, R from
    :func:`box_scratch`, out (nw, nx). Separable: heading AND, then y shift and erosion,
    then the x window. The scratch holds the band's nxh x rows of each word back to back
    (word w at w nxh), so that the y and x steps are each one loop over every word's rows
    (the band is short, 20-60 rows: one loop of nw nxh beats nw loops of nxh, 7 % of a
    level). Loops run over slice views from index 0 (a provably non-negative index lets
    LLVM vectorize them).
    """
    nw = out.shape[0]
    ox0, ox1, oy0, oy1 = box[0], box[1], box[2], box[3]
    xa = px + lo + ox0
    xb = px + hi + ox1 + 1
    nxh = xb - xa
    _heading_and(Wt, u, k0, h0, h1, pw + (oy0 >> 6), xa, xb, pw, nw, H)
    _erode_y(H, L, R, nw * nxh, nxh, np.uint64(oy0 & 63), oy1 - oy0 + 1)
    nbx = ox1 - ox0 + 1
    E, span = _window_x(L, R, nw * nxh, nbx)
    # E's row i of word w: the AND over x rows i .. i + span - 1; two such cover nbx.
    nb = hi + 1 - lo
    for w in range(nw):
        ow = out[w, lo : hi + 1]
        e0 = E[w * nxh : w * nxh + nb]
        e1 = E[w * nxh + nbx - span : w * nxh + nbx - span + nb]
        for i in range(nb):
            ow[i] = e0[i] & e1[i]


@njit_inline
def _heading_and(
    Wt: U64Array, u: int, k0: int, h0: int, h1: int, a: int, xa: int, xb: int, pw: int,
    nw: int, H: U64Array,
) -> None:  # fmt: skip
    """Fill H[q nxh + x], q < nw + 2: the AND over headings k0 + h0 .. k0 + h1 of Wt[u, k].

    Row q of H is word a + q over x rows xa .. xb - 1, zero where a + q is a padding
    word (outside the grid). Up to 5 headings (the paper grid's classes have 3 and 5) in
    one pass of 3 or 5 rows, a heading repeated where there are fewer (a second pass
    over a short band cost more than the loads); more: two headings per pass.
    """
    npsi = Wt.shape[1]
    nxh = xb - xa
    nh = h1 - h0 + 1
    last = nh - 1
    k_0 = (k0 + h0) % npsi
    k_1 = (k0 + h0 + min(1, last)) % npsi
    k_2 = (k0 + h0 + min(2, last)) % npsi
    k_3 = (k0 + h0 + min(3, last)) % npsi
    k_4 = (k0 + h0 + min(4, last)) % npsi
    for q in range(nw + 2):
        dst = H[q * nxh : (q + 1) * nxh]
        if a + q < pw or a + q >= pw + nw:
            for x in range(nxh):
                dst[x] = _ZERO
            continue
        s0 = Wt[u, k_0, a + q, xa:xb]
        s1 = Wt[u, k_1, a + q, xa:xb]
        s2 = Wt[u, k_2, a + q, xa:xb]
        if nh <= 3:
            for x in range(nxh):
                dst[x] = s0[x] & s1[x] & s2[x]
            continue
        s3 = Wt[u, k_3, a + q, xa:xb]
        s4 = Wt[u, k_4, a + q, xa:xb]
        for x in range(nxh):
            dst[x] = s0[x] & s1[x] & s2[x] & s3[x] & s4[x]
        ok = 5
        while ok < nh:
            s0 = Wt[u, (k0 + h0 + ok) % npsi, a + q, xa:xb]
            s1 = Wt[u, (k0 + h0 + min(ok + 1, last)) % npsi, a + q, xa:xb]
            for x in range(nxh):
                dst[x] &= s0[x] & s1[x]
            ok += 2


@njit_inline
def _erode_y(
    H: U64Array, L: U64Array, R: U64Array, n2: int, nxh: int, s: np.uint64, n: int
) -> None:
    """Fill L[:n2] with bits s .. s + 63 of H's word pairs (q, q + 1), eroded over n cells.

    L's bit b of word w: all of cells 64 w + b + s .. + n - 1 (in word pairs of H, a
    128-bit window); R holds the upper word of each pair, eroded alongside, by doubling.
    Up to 16 cells (the paper grid's boxes span 3-9) in one pass, the pair kept in
    registers: three doublings (a step of 0 changes nothing) and the rest.
    """
    hv0 = H[:n2]
    hv1 = H[nxh : nxh + n2]
    hv2 = H[2 * nxh : 2 * nxh + n2]
    lf = L[:n2]
    rf = R[:n2]
    if n <= 16:
        d1 = _ONE if n >= 2 else _ZERO
        d2 = np.uint64(2) if n >= 4 else _ZERO
        d3 = np.uint64(4) if n >= 8 else _ZERO
        d4 = np.uint64(n - (8 if n >= 8 else 4 if n >= 4 else 2 if n >= 2 else 1))
        for x in range(n2):
            lv = shifted(hv0[x], hv1[x], s)
            rv = shifted(hv1[x], hv2[x], s)
            lv &= shifted(lv, rv, d1)
            rv &= rv >> d1
            lv &= shifted(lv, rv, d2)
            rv &= rv >> d2
            lv &= shifted(lv, rv, d3)
            rv &= rv >> d3
            lf[x] = lv & shifted(lv, rv, d4)
        return
    for x in range(n2):
        lf[x] = shifted(hv0[x], hv1[x], s)
        rf[x] = shifted(hv1[x], hv2[x], s)
    span = 1
    while 2 * span <= n:
        d = np.uint64(span)
        for x in range(n2):
            lv = lf[x]
            rv = rf[x]
            lf[x] = lv & shifted(lv, rv, d)
            rf[x] = rv & (rv >> d)
        span *= 2
    if n > span:
        d = np.uint64(n - span)
        for x in range(n2):
            lf[x] = lf[x] & shifted(lf[x], rf[x], d)


@njit_inline
def _window_x(L: U64Array, R: U64Array, n2: int, nbx: int) -> tuple[U64Array, int]:
    """AND each row with the next ones by doubling, ping-pong in L and R; return (E, span).

    E (L or R): row x is the AND of rows x .. x + span - 1 (span the largest power of 2
    <= nbx), valid where x + span - 1 lies in the same word's rows. A flat pass also
    computes rows that mix two words' rows; those are never read as valid.
    """
    src = L
    dst = R
    span = 1
    valid = n2
    while 2 * span <= nbx:
        valid -= span
        e0 = src[:valid]
        e1 = src[span : span + valid]
        d = dst[:valid]
        for x in range(valid):
            d[x] = e0[x] & e1[x]
        src, dst = dst, src
        span *= 2
    return src, span


@njit_inline
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


@njit_inline
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
