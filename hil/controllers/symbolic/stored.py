"""Controllers to and from the solved-controller store: the files' arrays as controllers.

:mod:`hil.controllers.symbolic.store` keeps the files (keys, size bound, validation);
this module turns a stored solve into a :class:`Controller` and a finished one into a
stored solve, written from a thread.
"""

from __future__ import annotations

import threading
import time

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.abstraction import N_CLASSES, Tables
from hil.controllers.symbolic.controller import Controller, SynthesisStats
from hil.controllers.symbolic.lattice import InputLattice
from hil.controllers.symbolic.store import ControllerStore, SolvedLayout
from hil.core.arrays import BoolArray, U64Array

I32Array = NDArray[np.int32]

__all__ = ["StoredControllers"]


class StoredControllers:
    """Reads and writes one grid's controllers in the store.

    Args:
        store: The store (None: none, every solve is solved).
        tables: The grid's abstraction tables.
        lattice: Its input lattice.
        n_planes: Value bit planes of a controller.
    """

    def __init__(
        self, store: ControllerStore | None, tables: Tables, lattice: InputLattice, n_planes: int
    ) -> None:
        self._store = store
        self._n_planes = n_planes
        self._tables = tables
        self._lattice = lattice
        self._writes: list[threading.Thread] = []

    @property
    def enabled(self) -> bool:
        """Whether there is a store to read and write."""
        return self._store is not None and self._store.enabled

    def load(
        self,
        key: str,
        pads: I32Array,
        target: BoolArray,
        obstacles: BoolArray,
        free_cells: int,
    ) -> Controller | None:
        """Return the controller stored under `key` (winning bits padded by `pads`), or None."""
        if self._store is None:
            return None
        nx, ny, npsi = self._tables.grid.shape
        m = self._tables.n_inputs
        start = time.perf_counter()
        nw = (ny + 63) // 64
        words = (m, npsi, nw, nx)
        solved = self._store.load(
            key, (words, (m, npsi, nw, self._n_planes, nx), (N_CLASSES, m, npsi, nw, nx), words)
        )
        if solved is None:
            return None
        W, safe = (_padded(a, pads) for a in (solved.winning, solved.safe))
        return Controller(
            self._tables, self._lattice, W, solved.planes, solved.viable, pads,
            obstacles.astype(bool), SynthesisStats(
                levels=solved.levels, seconds=solved.solve_seconds, winning_cells=0,
                free_cells=free_cells, target_cells=int(target.sum()),
                threads=solved.threads, loaded_seconds=time.perf_counter() - start,
            ), safe,
        )  # fmt: skip

    def write(self, key: str, controller: Controller) -> None:
        """Write `controller` to the store from a thread: compressing takes about a second.

        Not a daemon thread: a process that ends right after a solve still finishes
        the file (an interrupted write leaves only a temporary file).
        """
        store = self._store
        safe = controller.safe_words
        if store is None or safe is None:
            return  # only complete controllers (with their safety set) are stored
        px, _, pw = (int(p) for p in controller.pads)
        nx, ny, _ = self._tables.grid.shape
        s = controller.stats
        rows = (slice(None), slice(None), slice(pw, pw + (ny + 63) // 64), slice(px, px + nx))
        solved = SolvedLayout(
            controller.winning_words[rows], controller.value_planes, controller.viable_words,
            safe[rows], s.levels, s.seconds, s.threads,
        )  # fmt: skip
        thread = threading.Thread(
            target=store.save, args=(key, solved), name="hil-controller-store"
        )
        thread.start()
        self._writes = [t for t in self._writes if t.is_alive()] + [thread]

    def wait(self) -> None:
        """Block until every controller written is in the store."""
        while self._writes:
            self._writes.pop().join()


def _padded(words: U64Array, pads: I32Array) -> U64Array:
    """Return words (m, npsi, nw, nx) in the winning bits' padded layout."""
    m, npsi, nw, nx = words.shape
    px, _, pw = (int(p) for p in pads)
    out = np.zeros((m, npsi, nw + 2 * pw, nx + 2 * px), dtype=np.uint64)
    out[:, :, pw : pw + nw, px : px + nx] = words
    return out
