"""The fixed point's whole state, advanced one BFS level per call (:mod:`planes_kernel`).

A caller that watches a state can stop as soon as it joined: after each
:meth:`LevelSolver.advance`, every state of value <= :attr:`LevelSolver.level` holds its
final bit and value and no state of a larger value is set; :meth:`LevelSolver.export`
returns them in the layout the :class:`~hil.controllers.symbolic.controller.Controller`
reads: a copy of the winning bits (so a snapshot stays valid while the solve goes on)
and the value planes themselves (a joined state's planes never change again; a later
state's are hidden behind the copy's bits).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.planes_kernel import (
    advance_parallel,
    advance_serial,
    init_planes_state,
    solve_serial,
)
from hil.core.arrays import U64Array
from hil.core.jit import njit, numba_threads, thread_limit

I32Array = NDArray[np.int32]

__all__ = ["LevelSolver", "Outputs", "Scratch", "Watch"]

@dataclass(frozen=True, slots=True)
class Watch:
    """A state whose controller a solve hands out as soon as it covers it.

    Attributes:
        cell: Grid cell (i, j, k) of the vessel's estimate.
        reference: Input index of the reference in force (the previous command).
    """

    cell: tuple[int, int, int]
    reference: int

    def covered_by(self, winning: U64Array, pads: I32Array) -> bool:
        """Return whether the state has joined `winning`, in :mod:`frontier_kernel`'s layout.

        winning: shape (m, nx + 2 px, npsi + 2 ph, nw + 2 pw); pads (px, ph, pw).
        """
        i, j, k = self.cell
        px, ph, pw = (int(p) for p in pads)
        word = int(winning[self.reference, px + i, ph + k, pw + (j >> 6)])
        return bool((word >> (j & 63)) & 1)


_Args = tuple[
    U64Array, U64Array, U64Array, U64Array, U64Array,  # Wt, Bt, Vt, nA, nB
    I32Array, I32Array, I32Array, I32Array, I32Array,  # band_a, band_b, ch, succ, heading
    U64Array, U64Array, I32Array, I32Array, I32Array,  # D1, D2, band_1, band_2, lattice
    U64Array, I32Array,  # Pt, pads
]  # fmt: skip


@dataclass(frozen=True, slots=True)
class Scratch:
    """A solve's working arrays that no controller keeps, for the next solve to reuse.

    A fresh allocation of these (about 90 MB at the paper grid) costs its page faults
    inside the solve, 0.1-0.2 s on this machine; a reused set costs a memset. Shapes:
    bt (m, npsi, nw, nx); na, nb (npsi, m, nw, nx), heading first
    (:mod:`planes_kernel`); ch, band_a, band_b
    (m, npsi, 2); the join's dilation scratch d1, d2 (slots, m, nw, nx) and band_1,
    band_2 (slots, m, 2): one heading's at a time per thread (slots: the solve's threads).
    """

    bt: U64Array
    na: U64Array
    nb: U64Array
    d1: U64Array
    d2: U64Array
    ch: I32Array
    band_a: I32Array
    band_b: I32Array
    band_1: I32Array
    band_2: I32Array

    @staticmethod
    def allocate(m: int, npsi: int, nw: int, nx: int, slots: int = 1) -> Scratch:
        """Return a zeroed set for m layers of npsi x nw x nx words, `slots` join threads."""
        rows = (m, npsi, nw, nx)
        bt = np.zeros(rows, dtype=np.uint64)
        na, nb = (np.zeros((npsi, m, nw, nx), dtype=np.uint64) for _ in range(2))
        d1, d2 = (np.zeros((slots, m, nw, nx), dtype=np.uint64) for _ in range(2))
        ch, band_a, band_b = (np.zeros((m, npsi, 2), np.int32) for _ in range(3))
        band_1, band_2 = (np.zeros((slots, m, 2), np.int32) for _ in range(2))
        return Scratch(bt, na, nb, d1, d2, ch, band_a, band_b, band_1, band_2)

    def fits(self, m: int, npsi: int, nw: int, nx: int, slots: int = 1) -> bool:
        """Return whether this set serves a solve of that size on `slots` join threads."""
        return self.bt.shape == (m, npsi, nw, nx) and self.d1.shape[0] == slots

    def clear(self) -> None:
        """Zero the class-1 set (the other arrays are written before they are read)."""
        self.bt.fill(0)


@njit
def _touch_pages(flat: U64Array) -> None:
    """Write a zero every 4 KiB of `flat`, so the kernel maps (and zeroes) every page now."""
    for i in range(0, flat.shape[0], 512):
        flat[i] = 0


@dataclass(frozen=True, slots=True)
class Outputs:
    """A solve's result arrays, zero and with every page mapped before the solve starts.

    Each solve hands its winning bits and value planes to its controller, so every solve
    needs new ones (about 255 MB at the paper grid, plus 67 MB for an early controller's
    copy of the bits). Fresh, their first touch (page faults, the kernel zeroing each
    page) falls inside the solve's first levels and the early copy; prepared between
    solves (:class:`~hil.controllers.symbolic.synthesis.Synthesizer`'s
    ``prepare_outputs``), it does not. Shapes: wt and early (m, npsi, nw + 2 pw,
    nx + 2 px), pt (m, npsi, nw, n_planes, nx).
    """

    wt: U64Array
    pt: U64Array
    early: U64Array

    @staticmethod
    def shapes(m: int, npsi: int, nw: int, nx: int, pads: I32Array,
               n_planes: int) -> tuple[tuple[int, int, int, int], tuple[int, int, int, int, int]]:
        """Return the shapes (wt, pt) of a solve of m layers, npsi x nw x nx words."""
        px, _, pw = (int(p) for p in pads)
        return (m, npsi, nw + 2 * pw, nx + 2 * px), (m, npsi, nw, n_planes, nx)

    @staticmethod
    def allocate(m: int, npsi: int, nw: int, nx: int, pads: I32Array,
                 n_planes: int) -> Outputs:
        """Return zeroed arrays for such a solve, every page touched (GIL released)."""
        wt_shape, pt_shape = Outputs.shapes(m, npsi, nw, nx, pads, n_planes)
        wt, pt, early = (np.zeros(shape, dtype=np.uint64) for shape in (wt_shape, pt_shape,
                                                                          wt_shape))
        for array in (wt, pt, early):
            _touch_pages(array.reshape(-1))
        return Outputs(wt, pt, early)


class LevelSolver:
    """One solve of the game on :mod:`planes_kernel`, one level per :meth:`advance`.

    Args:
        goal: Target words, shape (nx, npsi, nw) (bit b of word w: cell j = 64 w + b).
        viable: Viable words, shape (3, m, npsi, nw, nx) (:mod:`viable`), read as they are.
        pads: (px, ph, pw) of the winning array, as :mod:`sweep` needs them.
        succ: Successor boxes (2, npsi, m, 4); heading: heading ranges (2, m, 2).
        lattice_shape: Points per axis of the input lattice (input (a, b, c) is index
            (a * n_b + b) * n_c + c; N(u): one step per axis, :class:`InputLattice`).
        n_planes: Value bit planes (at most 2**n_planes - 1 levels).
        threads: 1 runs on the calling thread; more use numba's threads (at most that many).
        scratch: Working arrays of an earlier solve of the same size to reuse
            (:attr:`scratch` hands them on once the solve is done); None allocates.
        outputs: Result arrays prepared ahead (:class:`Outputs`, zero); None (or of
            another size) allocates.
    """

    def __init__(
        self,
        goal: U64Array,
        viable: U64Array,
        pads: I32Array,
        succ: I32Array,
        heading: I32Array,
        lattice_shape: tuple[int, int, int],
        n_planes: int,
        threads: int = 1,
        scratch: Scratch | None = None,
        outputs: Outputs | None = None,
    ) -> None:
        nx, npsi, nw = goal.shape
        m = viable.shape[1]
        px, _, pw = (int(p) for p in pads)
        self.pads = np.ascontiguousarray(pads, dtype=np.int32)
        wt_shape, pt_shape = Outputs.shapes(m, npsi, nw, nx, pads, n_planes)
        self._early: U64Array | None = None
        if outputs is not None and outputs.pt.shape == pt_shape and outputs.wt.shape == wt_shape:
            self._pt, self._wt, self._early = outputs.pt, outputs.wt, outputs.early
        else:
            self._pt = np.zeros(pt_shape, dtype=np.uint64)
            self._wt = np.zeros(wt_shape, dtype=np.uint64)
        self.threads = max(1, int(threads))
        """Threads :meth:`advance` uses."""
        slots = self._threaded()[1] or 1
        if scratch is None or not scratch.fits(m, npsi, nw, nx, slots):
            scratch = Scratch.allocate(m, npsi, nw, nx, slots)
        else:
            scratch.clear()
        self._scratch = scratch
        self._ch = scratch.ch
        init_planes_state(goal, self._wt, self._ch, px, pw)
        self._bt = scratch.bt
        self._na = scratch.na
        self._nb = scratch.nb
        self._band_a = scratch.band_a
        self._band_b = scratch.band_b
        self._succ = np.ascontiguousarray(succ, dtype=np.int32)
        self._heading = np.ascontiguousarray(heading, dtype=np.int32)
        self._d1 = scratch.d1
        self._d2 = scratch.d2
        self._band_1 = scratch.band_1
        self._band_2 = scratch.band_2
        self._lattice = np.array(lattice_shape, dtype=np.int32)
        self.viable = viable
        """The viable words it was built on (the Controller keeps them; the kernel's Vt)."""
        self.level = 0
        """Every state of value <= level is final (0: the goal)."""
        self.done = False
        """The fixed point is reached: nothing joins at level + 1."""

    @property
    def scratch(self) -> Scratch | None:
        """Return the working arrays for another solve once this one is done, else None."""
        return self._scratch if self.done else None

    def _args(self) -> _Args:
        return (
            self._wt, self._bt, self.viable, self._na, self._nb, self._band_a, self._band_b,
            self._ch, self._succ, self._heading, self._d1, self._d2, self._band_1,
            self._band_2, self._lattice, self._pt, self.pads,
        )  # fmt: skip

    def _threaded(self) -> tuple[bool, int]:
        if self.threads == 1:
            return True, 0
        return False, thread_limit(self.threads)

    def advance(self) -> int:
        """Join the states of value level + 1; return how many (x, heading) rows changed.

        0: the fixed point (:attr:`done`, level unchanged); -1: level + 1 does not fit
        the planes (nothing joined).
        """
        if self.done:
            return 0
        serial, threads = self._threaded()
        if serial:
            n = int(advance_serial(self.level, *self._args()))
        else:
            with numba_threads(threads):
                n = int(advance_parallel(self.level, *self._args()))
        if n == 0:
            self.done = True
        elif n > 0:
            self.level += 1
        return n

    def solve(self) -> int:
        """Advance to the fixed point; return its level (the last with joins), -1: too many.

        Too many: the planes hold no more levels; the solve then stops there (:attr:`done`,
        :attr:`level` the planes' last): every state joined holds its final value, the
        states of larger values are not set.
        """
        if self.done:
            return self.level
        serial, _ = self._threaded()
        if serial:
            levels = int(solve_serial(self.level, *self._args()))
        else:  # one call per level: the parallel kernel's threads start once per level anyway
            n = 1
            while n > 0:
                n = self.advance()
            levels = self.level if n == 0 else -1
        if levels < 0:
            self.level = (1 << self._pt.shape[3]) - 1
        else:
            self.level = levels
        self.done = True
        return levels

    def joined(self, p: int, i: int, j: int, k: int) -> bool:
        """Return whether state (cell (i, j, k), reference p) has joined (value <= level).

        i, j, k must lie on the grid (0 <= i < nx, 0 <= j < ny, 0 <= k < npsi).
        """
        px, _, pw = (int(v) for v in self.pads)
        word = int(self._wt[p, k, pw + (j >> 6), px + i])
        return bool((word >> (j & 63)) & 1)

    def export(self) -> tuple[U64Array, U64Array]:
        """Return (W, planes) of the states joined so far, in the Controller's layout.

        W: shape (m, npsi, nw + 2 pw, nx + 2 px), a copy while the solve may go on, the
        solver's own array once :attr:`done`; planes: (m, npsi, nw, n_planes, nx), the
        solver's own array (read-only to the caller; see the module's docstring).
        """
        if self.done:
            return self._wt, self._pt
        if self._early is not None:  # prepared: no page faults on the way to the vessel
            winning, self._early = self._early, None
            # The padding (half the words) is zero in both arrays: copy the grid only.
            px, _, pw = (int(v) for v in self.pads)
            grid = (slice(None), slice(None), slice(pw, winning.shape[2] - pw),
                    slice(px, winning.shape[3] - px))
            np.copyto(winning[grid], self._wt[grid])
            return winning, self._pt
        return self._wt.copy(), self._pt
