"""The join of one BFS level of :mod:`planes_kernel`: new states into every layer, by heading.

For a heading k, every layer p gets the states that joined A_p (nA[k, p]) and those that
joined B_u (nB[k, u]) at a lattice neighbour u of p; the neighbours' union is taken
separably, one lattice axis at a time. Then the new states' value planes are set and
the rows that changed are recorded for the next level's sweep. Arrays and their layout:
:mod:`planes_kernel`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hil.core.arrays import U64Array
from hil.core.jit import njit, njit_inline
from hil.core.prefetch import prefetch_rows

I32Array = NDArray[np.int32]

__all__ = ["apply_heading"]

_ZERO = np.uint64(0)


@njit
def _or_into(acc: U64Array, src: U64Array, lo: int, a0: int, a1: int) -> None:
    """acc[i - lo] |= src[i] for i in [a0, a1] (1-D rows)."""
    n = a1 + 1 - a0
    if n <= 0:
        return
    dst = acc[a0 - lo : a1 + 1 - lo]
    s = src[a0 : a1 + 1]
    for i in range(n):
        dst[i] |= s[i]


@njit
def _dilate(
    src: U64Array,
    sband: I32Array,
    dst: U64Array,
    dband: I32Array,
    stride: int,
    size: int,
) -> None:
    """dst[u] = OR of src[v] over v = u and its neighbours u -+ stride on one lattice axis.

    The axis has `size` points, u's coordinate on it is (u // stride) % size. Arrays
    (m, nw, nx) of one heading, only each row's band [lo, hi] (bands (m, 2)) is read / set.
    The source the next layer adds (u + 1 + stride) is prefetched: the first pass reads
    the sweep's nB, long out of cache (0.7x the dilations' time at the paper grid).
    """
    m = src.shape[0]
    nw = src.shape[1]
    nx = src.shape[2]
    for u in range(m):
        ahead = u + 1 + stride
        if ahead < m:
            for w in range(nw):
                prefetch_rows(src[ahead, w], sband[ahead, 0], sband[ahead, 1])
        coord = (u // stride) % size
        v0 = u - stride if coord > 0 else u
        v1 = u + stride if coord < size - 1 else u
        lo = nx
        hi = -1
        for v in range(v0, v1 + 1, stride):
            if sband[v, 0] <= sband[v, 1]:
                lo = min(lo, sband[v, 0])
                hi = max(hi, sband[v, 1])
        dband[u, 0] = lo
        dband[u, 1] = hi
        if lo > hi:
            continue
        nb = hi + 1 - lo
        for w in range(nw):
            dw = dst[u, w, lo : hi + 1]
            for i in range(nb):
                dw[i] = _ZERO
            for v in range(v0, v1 + 1, stride):
                _or_into(dw, src[v, w], lo, sband[v, 0], sband[v, 1])


@njit
def apply_heading(
    k: int,
    level: int,
    Wt: U64Array,
    nA: U64Array,
    nB: U64Array,
    band_a: I32Array,
    band_b: I32Array,
    D1: U64Array,
    D2: U64Array,
    band_1: I32Array,
    band_2: I32Array,
    ch: I32Array,
    lattice: I32Array,
    Pt: U64Array,
    pads: I32Array,
    acc: U64Array,
) -> int:
    """Join nA[p] and the neighbours' nB[u] into every layer p at heading k; return rows changed.

    The union of nB over the 3 x 3 x 3 lattice box around p (clipped: N(p) and p) is
    taken separably, one axis at a time, in D1, D2 (m, nw, nx) with bands band_1, band_2
    (m, 2): one heading's scratch, small enough to stay in the core's cache from one
    axis to the next. It holds nB[p] too, which adds nothing: nB[p] is inside A_p, so
    inside W_p or nA[p]. acc (nw, nx): scratch for one layer's joined rows.
    Writes ch[:, k], heading k of Wt and of Pt only.
    """
    m = Wt.shape[0]
    nx = nA.shape[3]
    n_c = lattice[2]
    n_b = lattice[1]
    n_a = lattice[0]
    _dilate(nB[k], band_b[:, k], D1, band_1, 1, n_c)
    _dilate(D1, band_1, D2, band_2, n_c, n_b)
    _dilate(D2, band_2, D1, band_1, n_c * n_b, n_a)
    n_changed = 0
    for p in range(m):
        if p + 1 < m:
            _prefetch_join(p + 1, k, level, Wt, nA, Pt, band_a, band_1, pads)
        ch[p, k, 0] = nx
        ch[p, k, 1] = -1
        a0, a1 = band_a[p, k, 0], band_a[p, k, 1]
        d0, d1 = band_1[p, 0], band_1[p, 1]
        lo = min(a0, d0)
        hi = max(a1, d1)
        if lo > hi:
            continue
        if not _join_rows(acc, nA[k, p], (a0, a1), D1[p], (d0, d1), Wt[p, k], lo, hi, pads):
            continue
        _set_planes(Pt[p, k], acc, lo, hi, level)
        first, last, n = _changed_rows(acc, lo, hi + 1 - lo)
        n_changed += n
        ch[p, k, 0] = first
        ch[p, k, 1] = last
    return n_changed


@njit_inline
def _prefetch_join(
    p: int, k: int, level: int, Wt: U64Array, nA: U64Array, Pt: U64Array, band_a: I32Array,
    band_1: I32Array, pads: I32Array,
) -> None:  # fmt: skip
    """Prefetch the rows layer p's join at heading k reads and writes.

    Its new A rows (written by the sweep long before), its winning words and the value
    planes that `level` sets, over the band of its new states (0.85x the join's time at
    the paper grid; the new A rows 0.98x a level more).
    """
    lo = min(band_a[p, k, 0], band_1[p, 0])
    hi = max(band_a[p, k, 1], band_1[p, 1])
    if lo > hi:
        return
    px, pw = pads[0], pads[2]
    for w in range(Pt.shape[2]):
        prefetch_rows(Wt[p, k, pw + w], px + lo, px + hi)
        lv = level
        q = 0
        while lv > 0:
            if lv & 1:
                prefetch_rows(Pt[p, k, w, q], lo, hi)
            lv >>= 1
            q += 1
    for w in range(nA.shape[2]):
        prefetch_rows(nA[k, p, w], band_a[p, k, 0], band_a[p, k, 1])


@njit_inline
def _join_rows(
    acc: U64Array, new_a: U64Array, band_new_a: tuple[int, int], dilated_b: U64Array,
    band_dilated_b: tuple[int, int], Wt_pk: U64Array, lo: int, hi: int, pads: I32Array,
) -> bool:  # fmt: skip
    """Join rows [lo, hi] of one layer and heading: acc = (nA | dilated nB) and not W; W |= acc.

    new_a, dilated_b (nw, nx) with their bands [lo, hi]; Wt_pk (nw + 2 pw, nx + 2 px) the
    layer's winning words at this heading; acc (nw, nx) gets the states that joined in
    its first hi + 1 - lo rows. Return whether any did.
    """
    px, pw = pads[0], pads[2]
    nb = hi + 1 - lo
    joined = _ZERO
    for w in range(acc.shape[0]):
        aw = acc[w, :nb]
        for i in range(nb):
            aw[i] = _ZERO
        _or_into(aw, new_a[w], lo, band_new_a[0], band_new_a[1])
        _or_into(aw, dilated_b[w], lo, band_dilated_b[0], band_dilated_b[1])
        cur = Wt_pk[pw + w, px + lo : px + hi + 1]
        for i in range(nb):
            f = aw[i] & ~cur[i]
            aw[i] = f
            cur[i] |= f
            joined |= f
    return bool(joined != _ZERO)


@njit_inline
def _set_planes(Pt_pk: U64Array, acc: U64Array, lo: int, hi: int, level: int) -> None:
    """Set the value bit planes Pt_pk (nw, n_planes, nx) of acc's states to `level`.

    acc (nw, nx) holds rows lo .. hi from index 0; a plane q gets them where bit q of
    level is set (the others stay zero: the states are new).
    """
    nb = hi + 1 - lo
    for w in range(acc.shape[0]):
        aw = acc[w, :nb]
        q = 0
        lv = level
        while lv > 0:
            if lv & 1:
                pq = Pt_pk[w, q, lo : hi + 1]
                for i in range(nb):
                    pq[i] |= aw[i]
            lv >>= 1
            q += 1


@njit_inline
def _changed_rows(acc: U64Array, lo: int, nb: int) -> tuple[int, int, int]:
    """Return (first, last, count) of the rows lo + t, t < nb, where acc (nw, nx) has a bit.

    (-1, -1, 0): none.
    """
    first = -1
    last = -1
    n = 0
    for t in range(nb):
        row = _ZERO
        for w in range(acc.shape[0]):
            row |= acc[w, t]
        if row != _ZERO:
            n += 1
            if first < 0:
                first = lo + t
            last = lo + t
    return first, last, n
