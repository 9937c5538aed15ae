"""A level-at-a-time bit-plane kernel of the reach-avoid fixed point, x contiguous.

Same game and same result as :mod:`sweep` (bit-identical W and value planes), built for
latency: the caller advances the BFS one level per call (:func:`advance_serial`,
:func:`advance_parallel`), so it can stop once a watched state joined and go on later.

Layout (x contiguous, so every step is a vector operation over a band of x rows):

- ``Wt`` (m, npsi, nw + 2 pw, nx + 2 px): bit b of word pw + w at x index px + i of
  (layer u, heading k) is cell (i, 64 w + b, k). Padding is zero (outside the grid).
- ``Bt`` (m, npsi, nw, nx): the class-1 set B_u so far; ``nA``, ``nB`` (npsi, m, nw, nx):
  the states that joined A_u / B_u at the level being computed, heading first, so that a
  heading's join reads its rows of every layer from one contiguous block.
- ``Vt`` (3, m, npsi, nw, nx): the viable words (:mod:`viable`'s layout, read as they
  are; classes 0 and 1).
- ``ch`` (m, npsi, 2): the x range [lo, hi] of the rows of (u, k) that changed at the
  last level (lo > hi: none); ``band_a``, ``band_b`` (m, npsi, 2): the x range of the
  rows of nA / nB that hold any bit.
- ``Pt`` (m, npsi, nw, n_planes, nx): value bit planes (bit q of a state's value is its
  bit in plane q). Wt and Pt are the layout the Controller reads
  (:mod:`kernels`), so a finished solve hands them over without a copy, and an early
  controller needs only a copy of Wt: the planes' bits of a state joined so far are final,
  and those of later states stay hidden behind its Wt. :func:`from_sweep_layout` brings
  :mod:`sweep`'s result into this layout.

One level: for each input u and heading k, each class c's successor box
[ox0, ox1] x [oy0, oy1] x [h0, h1] is tested separably on the x band whose boxes reach a
row changed at the last level: AND over the heading rows k + h0 .. k + h1 (periodic),
shift by oy0 and erode over the oy1 - oy0 + 1 cells along y by doubling (a 128-bit pair
per word), then AND over the x window. A state's box test changes only if a cell of its
box changed at the last level, so states outside the band keep last level's result:
exact. Then each layer p joins nA_p and the nB_u of its lattice neighbours u in N(p).

Exactness against :mod:`sweep`, which computes B_u only on candidates in
W_u or joining A_u (this kernel on every viable state of the band): with box1
containing box0, heading1 containing heading0 and viable1 inside viable0
(:func:`nested_classes` checks all three; the Synthesizer uses :mod:`sweep` otherwise),
viable1 and Pre1(W_u) imply viable0 and Pre0(W_u), so that
restriction removes nothing and B_u = viable1 and Pre1(W_u). Only B's new states need
joining: the older ones joined W_p at their own level. A state's value is the level it
joined at, the same BFS levels as :mod:`sweep`.
"""

from __future__ import annotations

import numpy as np
from numba import prange
from numpy.typing import NDArray

from hil.controllers.symbolic.box_test import (
    box_scratch,
    box_test,
    changed_band,
    row_ends,
    split_box_scratch,
)
from hil.controllers.symbolic.planes_join import apply_heading
from hil.core.arrays import U64Array
from hil.core.borrow import borrowed
from hil.core.jit import njit, njit_inline, njit_parallel
from hil.core.prefetch import prefetch_rows

I32Array = NDArray[np.int32]

__all__ = [
    "advance_parallel",
    "advance_serial",
    "from_sweep_layout",
    "init_planes_state",
    "nested_classes",
    "solve_serial",
]

_ZERO = np.uint64(0)


def nested_classes(succ: I32Array, heading: I32Array, viable: U64Array) -> bool:
    """Return whether class 1's boxes, heading ranges and viable words contain class 0's.

    succ (2, npsi, m, 4) = (ox0, ox1, oy0, oy1); heading (2, m, 2); viable (3, m, nx,
    npsi, nw). Containment is what makes this kernel's B_u equal :mod:`sweep`'s.
    """
    s0, s1 = succ[0], succ[1]
    boxes = bool(
        np.all(s1[..., 0] <= s0[..., 0])
        and np.all(s1[..., 1] >= s0[..., 1])
        and np.all(s1[..., 2] <= s0[..., 2])
        and np.all(s1[..., 3] >= s0[..., 3])
    )
    heads = bool(
        np.all(heading[1, :, 0] <= heading[0, :, 0])
        and np.all(heading[1, :, 1] >= heading[0, :, 1])
    )
    return boxes and heads and _contains(viable[0].reshape(-1), viable[1].reshape(-1))


@njit
def _contains(outer: U64Array, inner: U64Array) -> bool:
    """Return whether every bit of inner is set in outer (1-D, same length).

    Without numpy's temporaries: two 27-MB arrays' page faults cost more than the test
    (7 -> 2 ms at the paper grid).
    """
    extra = _ZERO
    for i in range(outer.shape[0]):
        extra |= inner[i] & ~outer[i]
    return bool(extra == _ZERO)


@njit
def init_planes_state(goal: U64Array, Wt: U64Array, ch: I32Array, px: int, pw: int) -> None:
    """Set every layer of Wt to the goal words (nx, npsi, nw) and ch to the goal's rows.

    :mod:`sweep`'s W is set by :func:`sweep.init_layers`; here the goal rows are the rows
    "changed at level 0", so the first level tests every box that reaches them.
    """
    m = Wt.shape[0]
    nx, npsi, nw = goal.shape
    for u in range(m):
        for k in range(npsi):
            ch[u, k, 0] = nx
            ch[u, k, 1] = -1
    for i in range(nx):
        for k in range(npsi):
            anyb = False
            for w in range(nw):
                if goal[i, k, w] != _ZERO:
                    anyb = True
            if not anyb:
                continue
            for u in range(m):
                for w in range(nw):
                    Wt[u, k, pw + w, px + i] = goal[i, k, w]
                ch[u, k, 0] = min(ch[u, k, 0], i)
                ch[u, k, 1] = max(ch[u, k, 1], i)


@njit_inline
def _prefetch_slab(
    u: int, k0: int, Wt: U64Array, Bt: U64Array, Vt: U64Array, bands: I32Array,
    succ: I32Array, heading: I32Array, px: int, pw: int,
) -> None:  # fmt: skip
    """Prefetch the rows slab (u, k0)'s sweep reads.

    For each class with a band: its viable and (class 1) B rows, (class 0) the winning
    rows it masks with, and the winning rows of the heading its box reaches last (the
    slab before read the others). Not the new-state rows: :func:`_store_new` writes few.
    """
    npsi = Wt.shape[1]
    nw = Bt.shape[2]
    for c in range(2):
        lo, hi = bands[k0, c, 0], bands[k0, c, 1]
        if lo > hi:
            continue
        for w in range(nw):
            prefetch_rows(Vt[c, u, k0, w], lo, hi)
            if c == 0:
                prefetch_rows(Wt[u, k0, pw + w], px + lo, px + hi)
            else:
                prefetch_rows(Bt[u, k0, w], lo, hi)
        box = succ[c, k0, u]
        k = (k0 + heading[c, u, 1]) % npsi
        a = pw + (box[2] >> 6)
        for q in range(max(a, pw), min(a + nw + 2, pw + nw)):
            prefetch_rows(Wt[u, k, q], px + lo + box[0], px + hi + box[1])


@njit
def _sweep_input(
    u: int,
    Wt: U64Array,
    Bt: U64Array,
    Vt: U64Array,
    nA: U64Array,
    nB: U64Array,
    band_a: I32Array,
    band_b: I32Array,
    ch: I32Array,
    succ: I32Array,
    heading: I32Array,
    px: int,
    pw: int,
    words: U64Array,
    bands: I32Array,
) -> None:
    """Compute nA[u], nB[u] and their bands for the next level; add nB[u] to Bt[u].

    Reads Wt[u] and ch[u] only, writes only input u's entries (threads may run inputs
    side by side). Every row of the changed band is box-tested: a first pass that kept
    only the rows holding a candidate (viable, not yet joined) cost more than the tests
    it saved (0.9x a level without it, paper grid). The joined rows' band comes from
    `rows` (the OR of a row's words), so every loop runs over contiguous x and vectorizes.
    The bands of every heading are found first, so that each slab prefetches the next
    one's rows (:mod:`hil.core.prefetch`; 0.75x the sweep's time at the paper grid).
    words: :func:`box_test.box_scratch`; bands (npsi, 2, 2): scratch, borrowed.
    """
    npsi = Wt.shape[1]
    nw = Bt.shape[2]
    nx = Bt.shape[3]
    H, L, R, out, rows = split_box_scratch(words, nw, Wt.shape[3], nx)
    for k0 in range(npsi):
        for c in range(2):
            lo, hi = changed_band(ch, u, k0, heading[c, u, 0], heading[c, u, 1],
                                  succ[c, k0, u], nx)
            bands[k0, c, 0] = lo
            bands[k0, c, 1] = hi
    for k0 in range(npsi):
        if k0 + 1 < npsi:
            _prefetch_slab(u, k0 + 1, Wt, Bt, Vt, bands, succ, heading, px, pw)
        for c in range(2):
            band = band_a if c == 0 else band_b
            band[u, k0, 0] = nx
            band[u, k0, 1] = -1
            lo, hi = bands[k0, c, 0], bands[k0, c, 1]
            if lo > hi:
                continue
            h0 = heading[c, u, 0]
            h1 = heading[c, u, 1]
            box = succ[c, k0, u]
            nb = hi + 1 - lo
            box_test(Wt, u, k0, h0, h1, box, lo, hi, px, pw, H, L, R, out)
            r = rows[:nb]
            for i in range(nb):
                r[i] = _ZERO
            for w in range(nw):
                vw = Vt[c, u, k0, w, lo : hi + 1]
                ow = out[w, lo : hi + 1]
                old = (Wt[u, k0, pw + w, px + lo : px + hi + 1] if c == 0
                       else Bt[u, k0, w, lo : hi + 1])
                for i in range(nb):
                    g = vw[i] & ~old[i] & ow[i]
                    ow[i] = g
                    r[i] |= g
            first, last = row_ends(rows, lo, nb, nx)
            band[u, k0, 0], band[u, k0, 1] = first, last
            _store_new(nA if c == 0 else nB, Bt, c, u, k0, out, first, last)


@njit_inline
def _store_new(
    dst: U64Array, Bt: U64Array, c: int, u: int, k0: int, out: U64Array, first: int,
    last: int,
) -> None:  # fmt: skip
    """Store the new states out[:, first .. last] as dst[k0, u] (class 1: into Bt[u, k0] too).

    Only the rows between the first and last holding a new state are written, never
    read elsewhere: 90 % of class 0's tested rows and 40 % of class 1's hold none, and
    their stores were a third of a level's memory traffic.
    """
    n = last + 1 - first
    for w in range(out.shape[0]):
        src = out[w, first : last + 1]
        dw = dst[k0, u, w, first : last + 1]
        for i in range(n):
            dw[i] = src[i]
        if c == 1:
            bw = Bt[u, k0, w, first : last + 1]
            for i in range(n):
                bw[i] |= src[i]


@njit
def advance_serial(
    level: int,
    Wt: U64Array,
    Bt: U64Array,
    Vt: U64Array,
    nA: U64Array,
    nB: U64Array,
    band_a: I32Array,
    band_b: I32Array,
    ch: I32Array,
    succ: I32Array,
    heading: I32Array,
    D1: U64Array,
    D2: U64Array,
    band_1: I32Array,
    band_2: I32Array,
    lattice: I32Array,
    Pt: U64Array,
    pads: I32Array,
) -> int:
    """Join the states of value level + 1 on the calling thread; return the rows changed.

    0: the fixed point (nothing joined); -1: level + 1 does not fit the planes. On entry
    every state of value <= level is set (after :func:`init_planes_state` and
    :func:`sweep.init_layers` for level 0, or the previous call) and ch holds the rows
    that changed at `level`.
    """
    if level + 1 > (1 << Pt.shape[3]) - 1:
        return -1
    # Borrowed views: the caller holds the arrays for the whole call (hil.core.borrow).
    Wt, Bt, Vt, nA, nB = borrowed(Wt), borrowed(Bt), borrowed(Vt), borrowed(nA), borrowed(nB)
    band_a, band_b, ch = borrowed(band_a), borrowed(band_b), borrowed(ch)
    succ, heading, lattice = borrowed(succ), borrowed(heading), borrowed(lattice)
    D1, D2, band_1, band_2 = borrowed(D1), borrowed(D2), borrowed(band_1), borrowed(band_2)
    Pt, pads = borrowed(Pt), borrowed(pads)
    m, npsi = Wt.shape[0], Wt.shape[1]
    nw, nx = Bt.shape[2], Bt.shape[3]
    px, pw = pads[0], pads[2]
    words = box_scratch(nw, Wt.shape[3], nx)
    bands = np.empty((npsi, 2, 2), dtype=np.int32)
    for u in range(m):
        _sweep_input(u, Wt, Bt, Vt, nA, nB, band_a, band_b, ch, succ, heading, px, pw,
                     borrowed(words), borrowed(bands))
    acc = np.empty((nw, nx), dtype=np.uint64)
    n = 0
    for k in range(npsi):
        n += apply_heading(
            k, level + 1, Wt, nA, nB, band_a, band_b, D1[0], D2[0], band_1[0], band_2[0], ch,
            lattice, Pt, pads, borrowed(acc),
        )  # fmt: skip
    return n


@njit_parallel
def advance_parallel(
    level: int,
    Wt: U64Array,
    Bt: U64Array,
    Vt: U64Array,
    nA: U64Array,
    nB: U64Array,
    band_a: I32Array,
    band_b: I32Array,
    ch: I32Array,
    succ: I32Array,
    heading: I32Array,
    D1: U64Array,
    D2: U64Array,
    band_1: I32Array,
    band_2: I32Array,
    lattice: I32Array,
    Pt: U64Array,
    pads: I32Array,
) -> int:
    """:func:`advance_serial` with the inputs' sweeps and the headings' joins threaded.

    A sweep writes only its input's entries, a heading's join only that heading's; the
    joins run as one task per scratch slot (D1.shape[0]), each over every slots-th heading
    with its own scratch.
    """
    if level + 1 > (1 << Pt.shape[3]) - 1:
        return -1
    # Borrowed views: the caller holds the arrays for the whole call (hil.core.borrow).
    Wt, Bt, Vt, nA, nB = borrowed(Wt), borrowed(Bt), borrowed(Vt), borrowed(nA), borrowed(nB)
    band_a, band_b, ch = borrowed(band_a), borrowed(band_b), borrowed(ch)
    succ, heading, lattice = borrowed(succ), borrowed(heading), borrowed(lattice)
    D1, D2, band_1, band_2 = borrowed(D1), borrowed(D2), borrowed(band_1), borrowed(band_2)
    Pt, pads = borrowed(Pt), borrowed(pads)
    m, npsi = Wt.shape[0], Wt.shape[1]
    nw, nx = Bt.shape[2], Bt.shape[3]
    px, pw = pads[0], pads[2]
    for u in prange(m):
        words = box_scratch(nw, Wt.shape[3], nx)
        bands = np.empty((npsi, 2, 2), dtype=np.int32)
        _sweep_input(u, Wt, Bt, Vt, nA, nB, band_a, band_b, ch, succ, heading, px, pw,
                     borrowed(words), borrowed(bands))
    slots = D1.shape[0]
    counts = np.zeros(slots, dtype=np.int64)
    for t in prange(slots):
        acc = np.empty((nw, nx), dtype=np.uint64)
        for k in range(t, npsi, slots):
            counts[t] += apply_heading(
                k, level + 1, Wt, nA, nB, band_a, band_b, D1[t], D2[t], band_1[t], band_2[t],
                ch, lattice, Pt, pads, borrowed(acc),
            )  # fmt: skip
    return int(counts.sum())


@njit
def solve_serial(
    level: int,
    Wt: U64Array,
    Bt: U64Array,
    Vt: U64Array,
    nA: U64Array,
    nB: U64Array,
    band_a: I32Array,
    band_b: I32Array,
    ch: I32Array,
    succ: I32Array,
    heading: I32Array,
    D1: U64Array,
    D2: U64Array,
    band_1: I32Array,
    band_2: I32Array,
    lattice: I32Array,
    Pt: U64Array,
    pads: I32Array,
) -> int:
    """Advance from `level` to the fixed point; return its level (-1: too many levels)."""
    while True:
        n = advance_serial(
            level, Wt, Bt, Vt, nA, nB, band_a, band_b, ch, succ, heading, D1, D2, band_1,
            band_2, lattice, Pt, pads,
        )  # fmt: skip
        if n < 0:
            return -1
        if n == 0:
            return level
        level += 1


@njit
def from_sweep_layout(
    W: U64Array, planes: U64Array, pads: I32Array, Wt: U64Array, Pt: U64Array
) -> None:
    """Write :mod:`sweep`'s result into this kernel's layout (the Controller's).

    W (m, nx + 2 px, npsi + 2 ph, nw + 2 pw) and planes (m, nx, npsi, nw, n_planes) into
    Wt (m, npsi, nw + 2 pw, nx + 2 px) and Pt (m, npsi, nw, n_planes, nx); Wt's padding
    is left as is (zero).
    """
    m, nx, npsi, nw, n_planes = planes.shape
    px, ph, pw = pads[0], pads[1], pads[2]
    for p in range(m):
        for i in range(nx):
            for k in range(npsi):
                for w in range(nw):
                    Wt[p, k, pw + w, px + i] = W[p, px + i, ph + k, pw + w]
                    for q in range(n_planes):
                        Pt[p, k, w, q, i] = planes[p, i, k, w, q]
