"""The viable words of a layout: which (class, input, cell) tubes the hull may fly.

A state (cell, heading) with input u in force is viable for class c when the swept tube
of u from it, under class c's deviation budget, stays on cells free for the hull over
every heading it may take. The words are computed per hull heading range from the
packed free masks (:func:`_all_viable`); a new layout starts from the last one's, and
only the cells whose tubes cross a column the masks changed in are computed again (a
moved obstacle touches a few columns).

Layout (3, m, npsi, nw, nx), x contiguous: bit b of word w at x index i of (class c,
input u, heading k) is cell (i, 64 w + b, k). The bit-plane kernels read it as it is
(:mod:`planes_kernel`, :mod:`safety_kernel`), and a tube's words over a run of x are
one contiguous store (cell-major, each x was a cache line of its own: 0.3x the time of
a new layout's words at the paper grid). :func:`cell_major` gives the frontier kernel
its layout.
"""

from __future__ import annotations

import threading

import numpy as np
from numba import prange
from numpy.typing import NDArray

from hil.controllers.symbolic.abstraction import N_CLASSES, Tables
from hil.controllers.symbolic.frontier_kernel import shifted
from hil.controllers.symbolic.kernels import pack_rows
from hil.core.arrays import BoolArray, U64Array
from hil.core.borrow import borrowed
from hil.core.jit import njit, njit_inline, njit_parallel, numba_threads, thread_limit

I32Array = NDArray[np.int32]

__all__ = ["ViableWords", "cell_major", "erode_free"]

_ZERO = np.uint64(0)


class ViableWords:
    """The viable words of each layout asked for, reusing the last layout's.

    Args:
        tables: The abstraction tables (tubes, hull heading ranges).
        pads: The solver's padding (x, heading, word), shape (3,).
    """

    def __init__(self, tables: Tables, pads: I32Array) -> None:
        self._tables = tables
        self._pads = pads
        self.f_layers = int((tables.tube_y[..., 1] - tables.tube_y[..., 0]).max()) + 1
        """Eroded free-mask layers one computation holds (the tubes' largest y extent)."""
        ranges = tables.hull_range_index().ravel()  # flat (c, k, u) -> range
        self._order = np.ascontiguousarray(np.argsort(ranges, kind="stable").astype(np.int32))
        n_ranges = tables.hull_psi.shape[0] * tables.hull_psi.shape[1] * tables.hull_psi.shape[2]
        counts = np.bincount(ranges, minlength=n_ranges)
        self._starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
        self._n_ranges = n_ranges
        self._lock = threading.Lock()
        self._last: tuple[U64Array, U64Array] | None = None
        self._base: tuple[U64Array, U64Array] | None = None
        """(the last words, a copy of them in memory already mapped) from :meth:`prepare`."""

    def words(self, free: BoolArray, threads: int = 1) -> U64Array:
        """Return the viable words (3, m, npsi, nw, nx) of the free masks (n_ranges, nx, ny).

        `threads` > 1 computes the ranges on that many of numba's threads (at most
        NUMBA_NUM_THREADS).

        From the previous call's words where the masks differ in a few columns (a moved
        obstacle): only the cells whose tubes cross a changed column are computed again.
        The array returned is new (or the previous one, unchanged, if nothing changed):
        controllers keep it, so it is never written after it is returned.
        """
        t = self._tables
        nx, ny, npsi = t.grid.shape
        m = t.n_inputs
        px, _, pw = (int(p) for p in self._pads)
        nw = (ny + 63) // 64
        free_words = pack_rows(np.ascontiguousarray(free.reshape(-1, ny))).reshape(
            self._n_ranges, nx, nw
        )
        with self._lock:
            previous = self._last
            base, self._base = self._base, None
        columns = _changed_columns(None if previous is None else previous[0], free_words)
        if previous is not None and previous[0].shape == free_words.shape:
            if not np.any(columns[:, 0] <= columns[:, 1]):
                with self._lock:
                    self._base = base
                return previous[1]
            prepared = base is not None and base[0] is previous[1]
            viable = base[1] if base is not None and prepared else previous[1].copy()
        else:
            viable = np.zeros((N_CLASSES, m, npsi, nw, nx), dtype=np.uint64)
        slots = thread_limit(threads)
        f_pad = np.zeros((slots, nw + 2 * pw, nx + 2 * px), dtype=np.uint64)
        f_eroded = np.zeros((slots, self.f_layers, nw + 2 * pw, nx + 2 * px), dtype=np.uint64)
        args = (free_words, columns, self._order, self._starts, t.tube_x0, t.tube_n, t.tube_y,
                px, pw, f_pad, f_eroded, viable)
        if slots == 1:
            _all_viable(*args)
        else:
            with numba_threads(slots):
                _all_viable_parallel(*args)
        with self._lock:
            self._last = (free_words, viable)
        return viable

    def prepare(self) -> None:
        """Copy the last layout's words into new memory now, for the next layout to start from.

        The next :meth:`words` of a changed layout then writes into that copy instead of
        copying 81 MB (the paper grid) inside the solve: a fresh copy's page faults cost
        0.16-0.2 s on this machine, one already mapped nothing. Between solves (the
        vessel's re-synthesis, once a controller is handed out); holds one more such array.
        """
        with self._lock:
            last = self._last
            if last is None or (self._base is not None and self._base[0] is last[1]):
                return
        base = np.empty_like(last[1])
        np.copyto(base, last[1])
        with self._lock:
            if self._last is last:
                self._base = (last[1], base)


@njit
def erode_free(F0: U64Array, out: U64Array, r0: int = 0, r1: int = -1) -> None:
    """Fill out (layers, words, rows) from F0 (words, rows): y-runs of free cells.

    Layer h has bit j set iff bits j .. j + h of F0 all are (F0's last word pads). Only
    rows (x) r0 .. r1 are written (r1 < 0: to the last): each row erodes on its own, and
    rows are contiguous, so each step is one loop over the rows.
    """
    n_w, n_rows = F0.shape
    if r1 < 0:
        r1 = n_rows - 1
    n = r1 + 1 - r0
    for w in range(n_w):
        src = F0[w, r0 : r1 + 1]
        dst = out[0, w, r0 : r1 + 1]
        for t in range(n):
            dst[t] = src[t]
    for h in range(1, out.shape[0]):
        q = h >> 6
        s = np.uint64(h & 63)
        for w in range(n_w):
            prev = out[h - 1, w, r0 : r1 + 1]
            dst = out[h, w, r0 : r1 + 1]
            if w + q + 1 < n_w:
                lo_w = F0[w + q, r0 : r1 + 1]
                hi_w = F0[w + q + 1, r0 : r1 + 1]
                for t in range(n):
                    dst[t] = prev[t] & shifted(lo_w[t], hi_w[t], s)
            elif w + q < n_w:
                lo_w = F0[w + q, r0 : r1 + 1]
                for t in range(n):
                    dst[t] = prev[t] & (lo_w[t] >> s)
            else:
                for t in range(n):
                    dst[t] = _ZERO


@njit_inline
def _tube_words(
    Fe: U64Array, cls: int, k: int, u: int, tube_x0: I32Array, tube_n: I32Array,
    tube_y: I32Array, px: int, pw: int, out: U64Array, i_lo: int, i_hi: int, acc: U64Array,
) -> None:  # fmt: skip
    """Fill out[cls, u, k, :, i] for i in [i_lo, i_hi] (clipped to the grid): free tubes.

    Bit b of word w: the tube (class cls, input u, heading k) from cell (i, 64 w + b) is
    free. Fe holds the free cells eroded along y, shape (layers, nw + 2 pw, nx + 2 px); out
    has shape (3, m, npsi, nw, nx); acc (nw, nx) is scratch. One tube column at a time
    over every row, so that the column's layer, word and shift are read once (a new
    layout's words 66 -> 53-57 ms at the paper grid, one thread).
    """
    nw = out.shape[3]
    nx = out.shape[4]
    lo = max(i_lo, 0)
    hi = min(i_hi, nx - 1)
    if lo > hi:
        return
    n = hi + 1 - lo
    x0 = px + lo + tube_x0[cls, k, u]
    for w in range(nw):
        aw = acc[w, :n]
        for t in range(n):
            aw[t] = ~_ZERO
    for c in range(tube_n[cls, k, u]):
        y0 = tube_y[cls, k, u, c, 0]
        layer = Fe[tube_y[cls, k, u, c, 1] - y0]
        s = np.uint64(y0 & 63)
        for w in range(nw):
            a = pw + w + (y0 >> 6)
            f0 = layer[a, x0 + c : x0 + c + n]
            f1 = layer[a + 1, x0 + c : x0 + c + n]
            aw = acc[w, :n]
            for t in range(n):
                aw[t] &= shifted(f0[t], f1[t], s)
    for w in range(nw):
        aw = acc[w, :n]
        dst = out[cls, u, k, w, lo : hi + 1]
        for t in range(n):
            dst[t] = aw[t]


@njit_inline
def _range_viable(
    h: int, free_words: U64Array, columns: I32Array, order: I32Array, starts: I32Array,
    tube_x0: I32Array, tube_n: I32Array, tube_y: I32Array, px: int, pw: int, Fpad: U64Array,
    Fe: U64Array, acc: U64Array, out: U64Array,
) -> None:  # fmt: skip
    """Write the viable words of the tubes whose hull range is h (see :func:`_all_viable`)."""
    _, nx, nw = free_words.shape
    m = out.shape[1]
    npsi = out.shape[2]
    n_max = tube_n.max()
    if starts[h] == starts[h + 1] or columns[h, 0] > columns[h, 1]:
        return
    for w in range(nw):
        for i in range(nx):
            Fpad[pw + w, px + i] = free_words[h, i, w]
    # The tubes below read columns lo - n + 1 .. hi + n - 1 only (n <= n_max): the
    # other rows of Fe are neither eroded nor read.
    r0 = max(px + columns[h, 0] - n_max + 1, 0)
    r1 = min(px + columns[h, 1] + n_max - 1, Fpad.shape[1] - 1)
    erode_free(Fpad, Fe, r0, r1)
    for e in range(starts[h], starts[h + 1]):
        flat = order[e]
        u = flat % m
        ck = flat // m
        k = ck % npsi
        c = ck // npsi
        # Tube columns i + x0 .. i + x0 + n - 1 meet [lo, hi].
        x0 = tube_x0[c, k, u]
        i_lo = columns[h, 0] - x0 - tube_n[c, k, u] + 1
        i_hi = columns[h, 1] - x0
        _tube_words(Fe, c, k, u, tube_x0, tube_n, tube_y, px, pw, out, i_lo, i_hi, acc)


@njit
def _all_viable(
    free_words: U64Array,
    columns: I32Array,
    order: I32Array,
    starts: I32Array,
    tube_x0: I32Array,
    tube_n: I32Array,
    tube_y: I32Array,
    px: int,
    pw: int,
    Fpad: U64Array,
    Fe: U64Array,
    out: U64Array,
) -> None:
    """Fill out (3, m, npsi, nw, nx): viable words of every (class, input, heading cell).

    free_words (n_ranges, nx, nw) are the packed free masks; order[starts[h]:starts[h+1]]
    lists the flat (c, k, u) whose hull range is h. Only the cells whose tube crosses a
    column in columns[h] = [lo, hi] are written (lo > hi: none of range h; out holds the
    rest already): a tube is free or not by the columns it crosses alone. Fpad
    (slots, nw + 2 pw, nx + 2 px) and Fe (slots, layers, nw + 2 pw, nx + 2 px) are zeroed
    scratch, x contiguous; this serial kernel uses slot 0.
    """
    # Borrowed views: the caller holds the arrays for the whole call (hil.core.borrow).
    free_words, columns = borrowed(free_words), borrowed(columns)
    order, starts = borrowed(order), borrowed(starts)
    tube_x0, tube_n, tube_y = borrowed(tube_x0), borrowed(tube_n), borrowed(tube_y)
    Fpad, Fe, out = borrowed(Fpad), borrowed(Fe), borrowed(out)
    n_ranges, nx, nw = free_words.shape
    acc = np.empty((nw, nx), dtype=np.uint64)
    for h in range(n_ranges):
        _range_viable(h, free_words, columns, order, starts, tube_x0, tube_n, tube_y, px, pw,
                      Fpad[0], Fe[0], borrowed(acc), out)


@njit_parallel
def _all_viable_parallel(
    free_words: U64Array,
    columns: I32Array,
    order: I32Array,
    starts: I32Array,
    tube_x0: I32Array,
    tube_n: I32Array,
    tube_y: I32Array,
    px: int,
    pw: int,
    Fpad: U64Array,
    Fe: U64Array,
    out: U64Array,
) -> None:
    """:func:`_all_viable` on numba's threads, one task per scratch slot.

    Each task takes every slots-th range; ranges write disjoint (class, heading, input)
    words.
    """
    # Borrowed views: the caller holds the arrays for the whole call (hil.core.borrow).
    free_words, columns = borrowed(free_words), borrowed(columns)
    order, starts = borrowed(order), borrowed(starts)
    tube_x0, tube_n, tube_y = borrowed(tube_x0), borrowed(tube_n), borrowed(tube_y)
    Fpad, Fe, out = borrowed(Fpad), borrowed(Fe), borrowed(out)
    n_ranges, nx, nw = free_words.shape
    slots = Fpad.shape[0]
    for t in prange(slots):
        acc = np.empty((nw, nx), dtype=np.uint64)
        for h in range(t, n_ranges, slots):
            _range_viable(h, free_words, columns, order, starts, tube_x0, tube_n, tube_y,
                          px, pw, Fpad[t], Fe[t], borrowed(acc), out)


def _changed_columns(before: U64Array | None, after: U64Array) -> I32Array:
    """Return each hull range's changed x columns [lo, hi], shape (n_ranges, 2) (lo > hi: none).

    before, after: packed free masks (n_ranges, nx, nw); no `before`: every column.
    """
    n_ranges, nx, _ = after.shape
    out = np.empty((n_ranges, 2), dtype=np.int32)
    out[:, 0] = 0
    out[:, 1] = nx - 1
    if before is None or before.shape != after.shape:
        return out
    changed = np.any(before != after, axis=2)  # (n_ranges, nx)
    some = changed.any(axis=1)
    out[:, 0] = np.where(some, np.argmax(changed, axis=1), nx)
    out[:, 1] = np.where(some, nx - 1 - np.argmax(changed[:, ::-1], axis=1), -1)
    return out


@njit
def cell_major(viable: U64Array) -> U64Array:
    """Return viable (3, m, npsi, nw, nx) as a new array (3, m, nx, npsi, nw), cell-major.

    The frontier kernel's layout (:mod:`frontier_kernel`): a cell's words of every heading
    side by side.
    """
    n_classes, m, npsi, nw, nx = viable.shape
    out = np.empty((n_classes, m, nx, npsi, nw), dtype=np.uint64)
    for c in range(n_classes):
        for u in range(m):
            for k in range(npsi):
                for w in range(nw):
                    row = viable[c, u, k, w]
                    for i in range(nx):
                        out[c, u, i, k, w] = row[i]
    return out
