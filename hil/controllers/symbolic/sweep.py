"""Compiled frontier sweeps of the reach-avoid fixed point, 64 cells per machine word.

Layout: the winning set and its erosions live in one padded bit array
E of shape (layers, nx + 2 px, npsi + 2 ph, nw + 2 pw) (uint64). Bit b of word
pw + w in row (px + i, ph + k) is cell (i, j = 64 w + b, k). Layer h holds the winning
bits eroded along y by width h + 1 (bit j set iff cells j .. j + h all win), so that a
successor box [ox0, ox1] x [oy0, oy1] x [ok0, ok1] wins for 64 cells at once when

    AND over ox, ok of  E[oy1 - oy0, row (i + ox, k + ok)] shifted by oy0.

The padding removes every bounds check and modulo from the inner loop: rows outside
the grid stay zero (not winning: the tank walls), and heading rows k < 0 or k >= npsi
are copies of the rows they wrap to. The free bits F (obstacle-free cells), eroded the
same way, have shape (layers, nx + 2 px, nw + 2 pw) and test the swept tube.

The fixed point follows the frontier: after each level only rows within the stencil's
reach of rows that changed are swept, and each row word stops at the first inputs that
cover all its remaining candidates. Values are exact BFS levels (a cell joins at level
L + 1 from the cells of level <= L), identical to the explicit fixed point.
"""

from __future__ import annotations

import numpy as np
from numba import prange
from numpy.typing import NDArray

from hil.core.jit import njit, njit_parallel

U64Array = NDArray[np.uint64]
I32Array = NDArray[np.int32]
BoolArray = NDArray[np.bool_]

__all__ = ["fixed_point_parallel", "fixed_point_serial", "init_bits", "viable_bits"]

_ZERO = np.uint64(0)
_ONE = np.uint64(1)
_63 = np.uint64(63)


@njit
def _shifted(lo: np.uint64, hi: np.uint64, s: np.uint64) -> np.uint64:
    """Return bits s .. s + 63 of the 128-bit value hi:lo (0 <= s < 64), without a branch."""
    return (lo >> s) | ((hi << _ONE) << (_63 - s))


@njit
def _erode_row(E: U64Array, ip: int, kp: int, pw: int, nw: int) -> None:
    """Recompute layers 1.. of row (ip, kp) from layer 0."""
    for h in range(1, E.shape[0]):
        q = h >> 6
        s = np.uint64(h & 63)
        for wp in range(pw, pw + nw):
            E[h, ip, kp, wp] = E[h - 1, ip, kp, wp] & _shifted(
                E[0, ip, kp, wp + q], E[0, ip, kp, wp + q + 1], s
            )


@njit
def _copy_wraps(E: U64Array, ip: int, k: int, npsi: int, ph: int) -> None:
    """Copy row (ip, ph + k) to the padding rows that stand for the same heading."""
    kp = ph + k
    n_kp = E.shape[2]
    other = kp - npsi * ((kp) // npsi)
    while other < n_kp:
        if other != kp:
            for h in range(E.shape[0]):
                for wp in range(E.shape[3]):
                    E[h, ip, other, wp] = E[h, ip, kp, wp]
        other += npsi


@njit
def init_bits(
    goal_words: U64Array, free_words: U64Array, E: U64Array, F: U64Array, px: int, pw: int
) -> None:
    """Fill E (goal, every heading) and F (free cells) from packed rows of shape (nx, nw)."""
    nx, nw = goal_words.shape
    for i in range(nx):
        for w in range(nw):
            F[0, px + i, pw + w] = free_words[i, w]
            for kp in range(E.shape[2]):
                E[0, px + i, kp, pw + w] = goal_words[i, w]
    for h in range(1, F.shape[0]):
        q = h >> 6
        s = np.uint64(h & 63)
        for ip in range(px, px + nx):
            for wp in range(pw, pw + nw):
                F[h, ip, wp] = F[h - 1, ip, wp] & _shifted(
                    F[0, ip, wp + q], F[0, ip, wp + q + 1], s
                )
    for ip in range(px, px + nx):
        for kp in range(E.shape[2]):
            _erode_row(E, ip, kp, pw, nw)


@njit
def viable_bits(
    F: U64Array,
    core_x: I32Array,
    core_n: I32Array,
    core_y: I32Array,
    px: int,
    pw: int,
    out: U64Array,
) -> None:
    """Fill out (nx, npsi, nw): free cells whose tube core is free (the rest can never win).

    core_x[k, :core_n[k]] are x offsets and core_y[k, c] = (y0, y1) y offsets of the cells
    that every input's tube from heading k covers; an obstacle there blocks all inputs.
    """
    nx, npsi, nw = out.shape
    for i in range(nx):
        ip = px + i
        for k in range(npsi):
            for w in range(nw):
                wp = pw + w
                acc = F[0, ip, wp]
                for c in range(core_n[k]):
                    y0 = core_y[k, c, 0]
                    h = core_y[k, c, 1] - y0
                    a = wp + (y0 >> 6)
                    s = np.uint64(y0 & 63)
                    x = ip + core_x[k, c]
                    acc &= _shifted(F[h, x, a], F[h, x, a + 1], s)
                out[i, k, w] = acc


@njit
def _sweep_row(
    r: int,
    npsi: int,
    nw: int,
    px: int,
    ph: int,
    pw: int,
    E: U64Array,
    F: U64Array,
    VB: U64Array,
    succ: I32Array,
    heading: I32Array,
    tube_x0: I32Array,
    tube_n: I32Array,
    tube_y: I32Array,
    new: U64Array,
) -> None:
    """Set new[r] (shape (nw,)) to the cells of row r = i * npsi + k that join next."""
    i = r // npsi
    k = r % npsi
    ip = px + i
    kp = ph + k
    n_in = succ.shape[1]
    for w in range(nw):
        wp = pw + w
        cand = ~E[0, ip, kp, wp] & VB[i, k, w]
        found = _ZERO
        if cand != _ZERO:
            for u in range(n_in):
                oy0 = succ[k, u, 2]
                hy = succ[k, u, 3] - oy0
                a = wp + (oy0 >> 6)
                s = np.uint64(oy0 & 63)
                acc = cand
                for ox in range(succ[k, u, 0], succ[k, u, 1] + 1):
                    for ok in range(heading[u, 0], heading[u, 1] + 1):
                        acc &= _shifted(
                            E[hy, ip + ox, kp + ok, a], E[hy, ip + ox, kp + ok, a + 1], s
                        )
                        if acc == _ZERO:
                            break
                    if acc == _ZERO:
                        break
                if acc == _ZERO:
                    continue
                x0 = ip + tube_x0[k, u]
                for c in range(tube_n[k, u]):
                    ty0 = tube_y[k, u, c, 0]
                    ht = tube_y[k, u, c, 1] - ty0
                    at = wp + (ty0 >> 6)
                    st = np.uint64(ty0 & 63)
                    acc &= _shifted(F[ht, x0 + c, at], F[ht, x0 + c, at + 1], st)
                    if acc == _ZERO:
                        break
                if acc != _ZERO:
                    found |= acc
                    cand &= ~acc
                    if cand == _ZERO:
                        break
        new[r, w] = found


@njit
def _apply(
    active: I32Array,
    n_active: int,
    npsi: int,
    px: int,
    ph: int,
    pw: int,
    level: int,
    E: U64Array,
    new: U64Array,
    V: NDArray[np.int32],
    changed: BoolArray,
) -> int:
    """Add the new cells at value `level`, refresh their rows; return how many joined."""
    nw = new.shape[1]
    ny = V.shape[1]
    count = 0
    for a in range(n_active):
        r = active[a]
        i = r // npsi
        k = r % npsi
        any_new = False
        for w in range(nw):
            bits = new[r, w]
            if bits == _ZERO:
                continue
            any_new = True
            E[0, px + i, ph + k, pw + w] |= bits
            for b in range(64):
                if (bits >> np.uint64(b)) & _ONE:
                    j = 64 * w + b
                    if j < ny:
                        V[i, j, k] = level
                        count += 1
        if any_new:
            changed[r] = True
            _erode_row(E, px + i, ph + k, pw, nw)
            _copy_wraps(E, px + i, k, npsi, ph)
    return count


@njit
def _activate(
    changed: BoolArray,
    nx: int,
    npsi: int,
    px: int,
    ph: int,
    pw: int,
    nw: int,
    reach_x: I32Array,
    h_lo: int,
    h_hi: int,
    E: U64Array,
    VB: U64Array,
    active: I32Array,
) -> int:
    """Fill `active` with rows that can gain cells after `changed`; clear `changed`.

    Row (i, k) can gain only if a row (i + ox, k + ok) changed, ox in reach_x[k] (the
    min and max over inputs) and ok in [h_lo, h_hi], and it has a viable cell not yet won.
    """
    prefix = np.zeros(nx + 1, dtype=np.int32)
    n = 0
    for k in range(npsi):
        for i in range(nx):
            hit = 0
            for ok in range(h_lo, h_hi + 1):
                kk = k + ok  # wrap without a modulo (slow in this loop)
                while kk < 0:
                    kk += npsi
                while kk >= npsi:
                    kk -= npsi
                if changed[i * npsi + kk]:
                    hit = 1
                    break
            prefix[i + 1] = prefix[i] + hit
        for i in range(nx):
            lo = max(i + reach_x[k, 0], 0)
            hi = min(i + reach_x[k, 1], nx - 1)
            if lo > hi or prefix[hi + 1] - prefix[lo] == 0:
                continue
            for w in range(nw):
                if ~E[0, px + i, ph + k, pw + w] & VB[i, k, w] != _ZERO:
                    active[n] = i * npsi + k
                    n += 1
                    break
    for r in range(changed.shape[0]):
        changed[r] = False
    return n


@njit_parallel
def fixed_point_parallel(
    E: U64Array,
    F: U64Array,
    VB: U64Array,
    V: NDArray[np.int32],
    pads: I32Array,
    succ: I32Array,
    heading: I32Array,
    tube_x0: I32Array,
    tube_n: I32Array,
    tube_y: I32Array,
    reach_x: I32Array,
    changed: BoolArray,
    active: I32Array,
    new: U64Array,
) -> int:
    """Run the fixed point with threads; return the number of levels.

    On entry E and F come from :func:`init_bits`, VB from :func:`viable_bits` (the
    candidates: free cells that some input may leave safely), V is 0 on the target and -1 elsewhere,
    `changed` marks the target rows; pads = (px, ph, pw); `active` (nx * npsi,) and
    `new` (nx * npsi, nw) are scratch. On return E[0] and V hold the winning set and values.
    """
    nx, _, npsi = V.shape
    px, ph, pw = pads[0], pads[1], pads[2]
    nw = new.shape[1]
    h_lo = heading[:, 0].min()
    h_hi = heading[:, 1].max()
    n_active = _activate(changed, nx, npsi, px, ph, pw, nw, reach_x, h_lo, h_hi, E, VB, active)
    level = 0
    while n_active > 0:
        for a in prange(n_active):
            _sweep_row(
                active[a],
                npsi,
                nw,
                px,
                ph,
                pw,
                E,
                F,
                VB,
                succ,
                heading,
                tube_x0,
                tube_n,
                tube_y,
                new,
            )
        if _apply(active, n_active, npsi, px, ph, pw, level + 1, E, new, V, changed) == 0:
            break
        level += 1
        n_active = _activate(changed, nx, npsi, px, ph, pw, nw, reach_x, h_lo, h_hi, E, VB, active)
    return level


@njit
def fixed_point_serial(
    E: U64Array,
    F: U64Array,
    VB: U64Array,
    V: NDArray[np.int32],
    pads: I32Array,
    succ: I32Array,
    heading: I32Array,
    tube_x0: I32Array,
    tube_n: I32Array,
    tube_y: I32Array,
    reach_x: I32Array,
    changed: BoolArray,
    active: I32Array,
    new: U64Array,
) -> int:
    """Run the same fixed point as :func:`fixed_point_parallel` on the calling thread."""
    nx, _, npsi = V.shape
    px, ph, pw = pads[0], pads[1], pads[2]
    nw = new.shape[1]
    h_lo = heading[:, 0].min()
    h_hi = heading[:, 1].max()
    n_active = _activate(changed, nx, npsi, px, ph, pw, nw, reach_x, h_lo, h_hi, E, VB, active)
    level = 0
    while n_active > 0:
        for a in range(n_active):
            _sweep_row(
                active[a],
                npsi,
                nw,
                px,
                ph,
                pw,
                E,
                F,
                VB,
                succ,
                heading,
                tube_x0,
                tube_n,
                tube_y,
                new,
            )
        if _apply(active, n_active, npsi, px, ph, pw, level + 1, E, new, V, changed) == 0:
            break
        level += 1
        n_active = _activate(changed, nx, npsi, px, ph, pw, nw, reach_x, h_lo, h_hi, E, VB, active)
    return level
