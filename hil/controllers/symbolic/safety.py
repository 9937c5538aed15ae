"""The largest set the vessel can stay in forever, on the reach-avoid solve's abstraction.

:func:`solve_safe_set` runs :mod:`safety_kernel`'s greatest fixed point over the same
viable words, successor boxes and input lattice as the docking controller, so a state in
it has, at every decision, an input whose tube is free and whose successors are in it
again: the vessel stays off the grown obstacles and inside the walls for as long as it
flies those inputs, whether or not docking is winning. The runtime falls back on it when
docking is lost (a moving obstacle closed the passage) and resumes docking once the
state wins again.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.errors import GridError
from hil.controllers.symbolic.levels import Scratch
from hil.controllers.symbolic.safety_kernel import (
    init_safety_state,
    safety_iterate_parallel,
    safety_iterate_serial,
)
from hil.core.arrays import U64Array
from hil.core.jit import numba_threads

I32Array = NDArray[np.int32]

__all__ = ["MAX_SAFETY_ITERATIONS", "SafeSet", "solve_safe_set"]

MAX_SAFETY_ITERATIONS = 10_000
"""More iterations than any grid needs (each removes at least one state's last option);
reaching it means a bug, reported as an error."""


@dataclass(frozen=True, slots=True, eq=False)
class SafeSet:
    """The safety game's greatest fixed point.

    Attributes:
        bits: Safe states, shape (m, npsi, nw + 2 pw, nx + 2 px) (the winning bits'
            layout, :mod:`kernels`): bit b of word pw + w at x index px + i of layer p,
            heading k is cell (i, 64 w + b, k) with reference p in force.
        iterations: Iterations until nothing left the set.
    """

    bits: U64Array
    iterations: int


def solve_safe_set(
    viable: U64Array,
    pads: I32Array,
    succ: I32Array,
    heading: I32Array,
    neighbours: I32Array,
    n_neighbours: I32Array,
    threads: int = 1,
    scratch: Scratch | None = None,
) -> SafeSet:
    """Return the largest set of (cell, reference) states the vessel can stay in forever.

    Args:
        viable: Tube-free words per class, shape (3, m, npsi, nw, nx) (:mod:`viable`;
            classes 0, 1 used).
        pads: (px, ph, pw) of the result's padding (ph unused); px and pw must hold every
            successor box, as for the reach-avoid solve.
        succ: Successor boxes (ox0, ox1, oy0, oy1), shape (3, npsi, m, 4).
        heading: Successor heading ranges, shape (3, m, 2).
        neighbours: The input lattice's one-step neighbours, (m, 26), padded with -1.
        n_neighbours: How many each input has, (m,).
        threads: 1 runs on the calling thread; more use numba's threads.
        scratch: The working arrays of a finished reach solve on these same viable words
            (:class:`~hil.controllers.symbolic.levels.Scratch`), or None: its new-state
            arrays hold A and B, instead of fresh memory whose page faults would fall inside
            the full solve. The caller must not use them meanwhile.

    Raises:
        GridError: The iteration did not converge (a bug, never expected).
    """
    _, m, npsi, nw, nx = viable.shape
    px, _, pw = (int(p) for p in pads)
    rows = (m, npsi, nw, nx)
    at_size = m * npsi * nw * nx
    if scratch is not None and scratch.na.size == at_size:
        at = scratch.na.reshape(rows)  # contiguous: a view, written before it is read
        bt = scratch.nb.reshape(rows)
    else:
        at = np.empty(rows, dtype=np.uint64)
        bt = np.empty(rows, dtype=np.uint64)
    st = np.zeros((m, npsi, nw + 2 * pw, nx + 2 * px), dtype=np.uint64)
    ch = np.empty((m, npsi, 2), dtype=np.int32)
    band_a = np.empty((m, npsi, 2), dtype=np.int32)
    band_b = np.empty((m, npsi, 2), dtype=np.int32)
    nbr = np.ascontiguousarray(neighbours, dtype=np.int32)
    n_nbr = np.ascontiguousarray(n_neighbours, dtype=np.int32)
    init_safety_state(viable, nbr, n_nbr, st, at, bt, ch, px, pw)
    args = (
        st, at, bt, band_a, band_b, ch, np.ascontiguousarray(succ, dtype=np.int32),
        np.ascontiguousarray(heading, dtype=np.int32), nbr, n_nbr,
        np.ascontiguousarray(pads, dtype=np.int32), MAX_SAFETY_ITERATIONS,
    )  # fmt: skip
    if threads <= 1:
        iterations = int(safety_iterate_serial(*args))
    else:
        with numba_threads(threads):
            iterations = int(safety_iterate_parallel(*args))
    if iterations < 0:
        raise GridError(
            f"the safety fixed point did not converge in {MAX_SAFETY_ITERATIONS} iterations"
        )
    return SafeSet(st, iterations)
