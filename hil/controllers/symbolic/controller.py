"""The synthesized controller: winning sets and values over (cell, reference) plus tables.

Online it only looks up: the cell of the estimated state (static quantizer, Reissig et
al. 2016) and the reference in force p (the previous command), then every input within
one grid step of p whose swept tube is free and whose successors all win with a
strictly smaller value. A state outside the grid or the winning set gets no input and no
exception, as in SCOTS' `StaticController` lookup but without throwing.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.abstraction import N_CLASSES, Tables
from hil.controllers.symbolic.errors import ControllerFileError, SymbolicError
from hil.controllers.symbolic.grid import Grid
from hil.controllers.symbolic.kernels import (
    first_decision_cells,
    layer_values,
    safe_input_indices,
    state_value,
    state_values,
    staying_input_indices,
)
from hil.controllers.symbolic.lattice import InputLattice
from hil.core.arrays import BoolArray, FloatArray, U64Array

I32Array = NDArray[np.int32]

__all__ = ["CellDecision", "Controller", "SynthesisStats"]

_FORMAT = "hil-symbolic-controller-6"  # 6: viable words x contiguous
_TABLE_FIELDS = ("succ", "heading", "tube_x0", "tube_n", "tube_y", "hull_psi", "yaw_index")


@dataclass(frozen=True, slots=True)
class SynthesisStats:
    """Figures of one synthesis.

    Attributes:
        levels: Fixed-point iterations until no state joined (the largest value).
        seconds: Wall time of the synthesis for this layout (s), tables excluded.
        winning_cells: Cells winning from rest (reference zero), target included.
        free_cells: States (cell, heading cell) the hull may occupy at rest: inside the
            arena, off the obstacles, the centre off the inflated obstacles.
        target_cells: Cells in the target (all headings).
        peak_bytes: Largest memory the synthesis held at once (bytes, traced).
        threads: Threads the kernel ran on.
        complete: False for an early controller: the solve stopped after `levels`
            levels (the state it was asked for joined), so it holds every state of
            value <= `levels` with its final value and safe inputs, and no other.
        loaded_seconds: Wall time to read the controller from the solved-controller
            store (s); 0 when solved here (then `seconds` is this solve's, else the
            stored solve's).
    """

    levels: int
    seconds: float
    winning_cells: int
    free_cells: int
    target_cells: int
    peak_bytes: int = 0
    threads: int = 1
    complete: bool = True
    loaded_seconds: float = 0.0

    @property
    def loaded(self) -> bool:
        """Return True when the controller was read from the store, not solved here."""
        return self.loaded_seconds > 0.0

    @property
    def winning_fraction(self) -> float:
        """Return winning cells from rest over free cells (0 with no free cell)."""
        return self.winning_cells / self.free_cells if self.free_cells else 0.0


@dataclass(frozen=True, slots=True, eq=False)
class CellDecision:
    """What the controller answers at one cell: the one query a decision makes.

    Attributes:
        value: The decision's value (:meth:`Controller.cell_decision_value`); -1 when
            docking is not winning there.
        inputs: Input indices listed, shape (n,): the safe inputs for docking; where
            docking is not winning, those that keep the vessel in the safety set
            (`staying`); none in the target (hold) or where nothing is safe.
        staying: Docking is not winning and `inputs` keep the vessel in the safety set
            (:mod:`~hil.controllers.symbolic.safety`): wait there until docking wins again.
        successor_values: Per listed input, the largest value among its successor
            cells, shape (n,); -1 for staying inputs (they promise the safety set).
    """

    value: int
    inputs: I32Array
    staying: bool = False
    successor_values: I32Array = field(default_factory=lambda: np.empty(0, dtype=np.int32))


class Controller:
    """A reach-avoid controller over (cell, reference in force), with its safety set.

    Args:
        tables: The abstraction the controller was synthesized on.
        lattice: The inputs' one-step neighbourhoods.
        winning: Winning bits, shape (m, npsi, nw + 2 pw, nx + 2 px) (:mod:`kernels`).
        planes: Value bit planes, shape (m, npsi, nw, n_planes, nx).
        viable: Tube-free bits per class, shape (3, m, npsi, nw, nx) (:mod:`viable`).
        pads: (px, ph, pw): `winning`'s padding px in x cells and pw in words (ph, the
            frontier kernel's heading padding, is not used by this layout).
        obstacles: Cells touching an inflated obstacle, shape (nx, ny) (pictures).
        stats: Figures of the synthesis; `winning_cells` is filled in here.
        safe_set: The safety game's set (:mod:`~hil.controllers.symbolic.safety`), in
            `winning`'s layout; None: not solved (an early controller), so a state that
            does not win for docking has no input.
    """

    def __init__(
        self,
        tables: Tables,
        lattice: InputLattice,
        winning: U64Array,
        planes: U64Array,
        viable: U64Array,
        pads: I32Array,
        obstacles: BoolArray,
        stats: SynthesisStats,
        safe_set: U64Array | None = None,
    ) -> None:
        self._tables = tables
        self._lattice = lattice
        self._W = winning
        self._planes = planes
        self._viable = viable
        self._pads = np.ascontiguousarray(pads, dtype=np.int32)
        self._obstacles = np.ascontiguousarray(obstacles, dtype=bool)
        self._obstacles.flags.writeable = False
        self._out = np.empty(tables.n_inputs, dtype=np.int32)
        self._safe = safe_set
        m, npsi, nw, _, nx = planes.shape
        self._no_planes = np.zeros((m, npsi, nw, 0, nx), dtype=np.uint64)
        self._best = np.empty(1, dtype=np.int32)
        self._worsts = np.empty(tables.n_inputs, dtype=np.int32)
        self.rest_index = lattice.nearest(np.zeros(3))
        # The values from rest (30 ms at the paper grid) wait for their first reader: an
        # early controller goes in force at once. Its winning count is the rest layer's
        # set bits (no bit beyond the grid is ever set).
        self._rest_values: I32Array | None = None
        rest_words = winning[self.rest_index]
        self.stats = replace(stats, winning_cells=int(np.bitwise_count(rest_words).sum()))

    # ------------------------------------------------------------------ properties

    @property
    def grid(self) -> Grid:
        """Return the state grid."""
        return self._tables.grid

    @property
    def tables(self) -> Tables:
        """Return the abstraction's offset tables."""
        return self._tables

    @property
    def lattice(self) -> InputLattice:
        """Return the inputs' one-step neighbourhoods."""
        return self._lattice

    @property
    def inputs(self) -> FloatArray:
        """Return all inputs, shape (m, 3)."""
        return self._tables.inputs

    @property
    def values(self) -> I32Array:
        """Return V from rest (reference zero in force), shape (nx, ny, npsi); -1 losing."""
        if self._rest_values is None:
            rest_values = self.layer_values(self.rest_index)
            rest_values.flags.writeable = False
            self._rest_values = rest_values
        return self._rest_values

    def layer_values(self, previous: int) -> I32Array:
        """Return V with reference `previous` in force, shape (nx, ny, npsi); -1 losing."""
        out: I32Array = layer_values(self._W, self._planes, self._pads, previous, self.grid.ny)
        return out

    @property
    def winning_words(self) -> U64Array:
        """Return the winning bits, shape (m, npsi, nw + 2 pw, nx + 2 px) (do not write)."""
        return self._W

    @property
    def value_planes(self) -> U64Array:
        """Return the value bit planes, shape (m, npsi, nw, n_planes, nx) (do not write)."""
        return self._planes

    @property
    def viable_words(self) -> U64Array:
        """Return the tube-free bits per class, shape (3, m, npsi, nw, nx) (do not write)."""
        return self._viable

    @property
    def pads(self) -> I32Array:
        """Return (px, ph, pw), the padding of :attr:`winning_words` (x cells, unused, words)."""
        return self._pads

    @property
    def obstacles(self) -> BoolArray:
        """Return the cells touching an inflated obstacle (read-only), shape (nx, ny)."""
        return self._obstacles

    @property
    def nbytes(self) -> int:
        """Return the bytes of the controller's own arrays (bits, planes, viable, safe)."""
        arrays = [self._W, self._planes, self._viable]
        if self._safe is not None:
            arrays.append(self._safe)
        return sum(int(a.nbytes) for a in arrays)

    @property
    def safe_words(self) -> U64Array | None:
        """Return the safety set's bits (winning bits' layout), None if not solved."""
        return self._safe

    def safe_counts(self, previous: int | None = None) -> tuple[int, int]:
        """Return (states in the safety set, those of them not winning) with `previous` in force.

        Counted over the cells (nx, ny, npsi) of one layer (None: at rest); the second
        figure is where a vessel waits instead of docking. (0, 0) without a safety set.
        """
        if self._safe is None:
            return 0, 0
        p = self.reference_index(previous)
        safe = self._safe[p]
        waiting = safe & ~self._W[p]
        return (
            int(np.unpackbits(safe.view(np.uint8)).sum()),
            int(np.unpackbits(waiting.view(np.uint8)).sum()),
        )

    @property
    def has_winning_start(self) -> bool:
        """Return True when some cell outside the target wins from rest."""
        return self.stats.winning_cells > self.stats.target_cells

    def reference_index(self, previous: int | None) -> int:
        """Return the input index of the reference in force (`None`: at rest)."""
        return self.rest_index if previous is None else int(previous)

    # ------------------------------------------------------------------ lookups

    def cell_value(self, cell: tuple[int, int, int], previous: int | None = None) -> int:
        """Return V of a cell with reference `previous` in force; -1 if losing."""
        i, j, k = cell
        p = self.reference_index(previous)
        return int(state_value(self._W, self._planes, self._pads, p, i, j, k))

    def value(self, state: Iterable[float], previous: int | None = None) -> float:
        """Return V at the state's cell (periods to the target); inf if not winning."""
        cell = self.grid.cell_of(state)
        if cell is None:
            return math.inf
        v = self.cell_value(cell, previous)
        return math.inf if v < 0 else float(v)

    def is_winning(self, state: Iterable[float], previous: int | None = None) -> bool:
        """Return True when the state's cell wins with `previous` in force (target included)."""
        return math.isfinite(self.value(state, previous))

    def safe_input_indices_at(
        self, cell: tuple[int, int, int], previous: int | None = None, first: bool = False
    ) -> I32Array:
        """Return the indices into :attr:`inputs` of the safe inputs at a cell, shape (n,).

        Args:
            cell: The cell (i, j, k).
            previous: Index of the reference in force; None: at rest.
            first: The run's first command, with the vessel possibly still moving:
                every candidate is budgeted as a change (class 1) and must only lead
                into the winning set.
        """
        t = self._tables
        i, j, k = cell
        g = self.grid
        if not (0 <= i < g.nx and 0 <= j < g.ny and 0 <= k < g.npsi):
            return np.empty(0, dtype=np.int32)
        n = safe_input_indices(
            self._W,
            self._planes,
            self._viable,
            self._pads,
            t.succ,
            t.heading,
            self._lattice.neighbours,
            self._lattice.n_neighbours,
            g.ny,
            self.reference_index(previous),
            i,
            j,
            k,
            first,
            self._out,
            self._best,
            self._worsts,
        )
        return self._out[:n].copy()

    def decision_value(
        self, state: Iterable[float], previous: int | None = None, first: bool = False
    ) -> float:
        """Return the value a decision at `state` works with; inf when nothing is safe.

        V of the state's cell with `previous` in force; for a first decision (see
        :meth:`safe_input_indices_at`) 1 + the least largest successor value over the
        safe inputs, since the state need not win with `previous` held.
        """
        cell = self.grid.cell_of(state)
        if cell is None:
            return math.inf
        v = self.cell_decision_value(cell, previous, first)
        return math.inf if v < 0 else float(v)

    def cell_decision_value(
        self, cell: tuple[int, int, int], previous: int | None = None, first: bool = False
    ) -> int:
        """Return :meth:`decision_value` of a cell; -1 when nothing is safe there."""
        if not first:
            return self.cell_value(cell, previous)
        self.safe_input_indices_at(cell, previous, first=True)
        return int(self._best[0])

    def decide_at(
        self, cell: tuple[int, int, int], previous: int | None = None, first: bool = False
    ) -> CellDecision:
        """Return the value and the listed inputs at a cell: everything a decision asks.

        Docking first (:meth:`cell_decision_value`, :meth:`safe_input_indices_at`, each
        kernel run once); where docking is not winning, the inputs that keep the vessel
        in the safety set, if the controller has one (:meth:`staying_input_indices_at`).
        """
        g = self.grid
        i, j, k = cell
        if not (0 <= i < g.nx and 0 <= j < g.ny and 0 <= k < g.npsi):
            return CellDecision(-1, np.empty(0, dtype=np.int32))
        if first:
            inputs = self.safe_input_indices_at(cell, previous, first=True)
            value = int(self._best[0])
        else:
            value = self.cell_value(cell, previous)
            inputs = (
                self.safe_input_indices_at(cell, previous)
                if value > 0
                else np.empty(0, dtype=np.int32)
            )
        if value >= 0:
            return CellDecision(value, inputs, False, self._worsts[: inputs.size].copy())
        staying = self.staying_input_indices_at(cell, previous, first)
        return CellDecision(-1, staying, staying.size > 0, np.full(staying.size, -1, np.int32))

    def staying_input_indices_at(
        self, cell: tuple[int, int, int], previous: int | None = None, first: bool = False
    ) -> I32Array:
        """Return the inputs at a cell that keep the vessel in the safety set, shape (n,).

        Candidates and budget classes as :meth:`safe_input_indices_at`; an input stays
        when its tube is free and every successor is in the safety set with that input in
        force. Empty without a safety set, or off the grid.
        """
        g = self.grid
        i, j, k = cell
        if self._safe is None or not (0 <= i < g.nx and 0 <= j < g.ny and 0 <= k < g.npsi):
            return np.empty(0, dtype=np.int32)
        t = self._tables
        n = staying_input_indices(
            self._safe, self._no_planes, self._viable, self._pads, t.succ, t.heading,
            self._lattice.neighbours, self._lattice.n_neighbours, g.ny,
            self.reference_index(previous), i, j, k, first, self._out,
        )  # fmt: skip
        return self._out[:n].copy()

    def safe_at(
        self, layer: int, i: NDArray[np.int64], j: NDArray[np.int64], k: NDArray[np.int64]
    ) -> NDArray[np.bool_]:
        """Return whether cells (i, j, k), each (N,), are safe with `layer` in force.

        In the safety set (:mod:`~hil.controllers.symbolic.safety`); all False without one.
        """
        g = self.grid
        ii = np.asarray(i, dtype=np.int64)
        jj = np.asarray(j, dtype=np.int64)
        kk = np.mod(np.asarray(k, dtype=np.int64), g.npsi)
        ok = (ii >= 0) & (ii < g.nx) & (jj >= 0) & (jj < g.ny)
        out = np.zeros(ii.shape[0], dtype=bool)
        if self._safe is not None:
            found = state_values(
                self._safe, self._no_planes, self._pads, int(layer), ii[ok], jj[ok], kk[ok]
            )
            out[ok] = found >= 0
        return out

    def first_decision_winning(self, previous: int | None = None) -> BoolArray:
        """Return where a first decision finds a safe input, shape (nx, ny, npsi).

        `previous` is the reference in force (None: at rest); the target counts (a
        first decision there holds). What the runtime's first decision (start, after a
        stop) and a campaign's start draw call winning; :attr:`values` is the winning set
        with the reference held.
        """
        t = self._tables
        out: BoolArray = first_decision_cells(
            self._W, self._planes, self._viable, self._pads, t.succ, t.heading,
            self._lattice.neighbours, self._lattice.n_neighbours, self.grid.ny,
            self.reference_index(previous),
        )  # fmt: skip
        return out

    def values_at(
        self, layer: int, i: NDArray[np.int64], j: NDArray[np.int64], k: NDArray[np.int64]
    ) -> NDArray[np.int64]:
        """Return V of cells (i, j, k), each (N,), with input `layer` in force; -1 losing."""
        g = self.grid
        ii = np.asarray(i, dtype=np.int64)
        jj = np.asarray(j, dtype=np.int64)
        kk = np.mod(np.asarray(k, dtype=np.int64), g.npsi)
        ok = (ii >= 0) & (ii < g.nx) & (jj >= 0) & (jj < g.ny)
        out = np.full(ii.shape[0], -1, dtype=np.int64)
        out[ok] = state_values(
            self._W, self._planes, self._pads, int(layer), ii[ok], jj[ok], kk[ok]
        )
        return out

    def safe_inputs(
        self, state: Iterable[float], previous: int | None = None, first: bool = False
    ) -> FloatArray:
        """Return every safe input at the state, shape (n, 3) (u m/s, v m/s, r rad/s).

        Empty (shape (0, 3)) outside the grid, outside the winning set and in the target
        (the specification is met there; hold position).
        """
        cell = self.grid.cell_of(state)
        if cell is None:
            return np.empty((0, 3))
        out: FloatArray = self.inputs[self.safe_input_indices_at(cell, previous, first)]
        return out

    # ------------------------------------------------------------------ files

    def save(self, path: str | Path) -> None:
        """Write the controller (tables, winning bits, values, tubes, safety set) to a .npz."""
        t = self._tables
        g = self.grid
        with Path(path).open("wb") as fh:
            np.savez_compressed(
                fh,
                format=np.array(_FORMAT),
                grid=np.array(
                    [g.x_min_m, g.y_min_m, g.cell_x_m, g.cell_y_m, g.nx, g.ny, g.npsi],
                    dtype=np.float64,
                ),
                inputs=t.inputs,
                timing=np.array([t.tau_s, t.late_s]),
                keys=np.array([t.budget_key, t.key]),
                winning=self._W,
                planes=self._planes,
                viable=self._viable,
                safe=self._safe if self._safe is not None else np.zeros(0, dtype=np.uint64),
                pads=self._pads,
                obstacles=np.packbits(self._obstacles, axis=None),
                stats=np.array(list(asdict(self.stats).values()), dtype=np.float64),
                **{name: getattr(t, name) for name in _TABLE_FIELDS},
            )

    @classmethod
    def load(cls, path: str | Path) -> Controller:
        """Read a controller written by :meth:`save`.

        Raises:
            ControllerFileError: The file is missing, corrupt or of another format.
        """
        try:
            with np.load(Path(path), allow_pickle=False) as data:
                if str(data["format"]) != _FORMAT:
                    raise ControllerFileError(
                        f"{str(path)!r} has format {str(data['format'])!r}, want {_FORMAT!r}"
                    )
                gx = data["grid"]
                grid = Grid(
                    float(gx[0]), float(gx[1]), float(gx[2]), float(gx[3]),
                    int(gx[4]), int(gx[5]), int(gx[6]),
                )  # fmt: skip
                timing = data["timing"]
                keys = data["keys"]
                tables = Tables(
                    grid=grid,
                    inputs=np.ascontiguousarray(data["inputs"], dtype=np.float64),
                    tau_s=float(timing[0]),
                    late_s=float(timing[1]),
                    budget_key=str(keys[0]),
                    key=str(keys[1]),
                    **{name: np.ascontiguousarray(data[name]) for name in _TABLE_FIELDS},
                )
                winning = np.ascontiguousarray(data["winning"], dtype=np.uint64)
                planes = np.ascontiguousarray(data["planes"], dtype=np.uint64)
                viable = np.ascontiguousarray(data["viable"], dtype=np.uint64)
                pads = np.ascontiguousarray(data["pads"], dtype=np.int32)
                safe_raw = np.ascontiguousarray(data["safe"], dtype=np.uint64)
                safe = safe_raw if safe_raw.size else None
                obstacles = (
                    np.unpackbits(data["obstacles"], count=grid.nx * grid.ny)
                    .astype(bool)
                    .reshape(grid.nx, grid.ny)
                )
                s = data["stats"]
                # Files written before `complete` and `loaded_seconds` hold 7 figures.
                stats = SynthesisStats(
                    int(s[0]), float(s[1]), int(s[2]), int(s[3]), int(s[4]), int(s[5]), int(s[6]),
                    complete=bool(s[7]) if len(s) > 7 else True,
                    loaded_seconds=float(s[8]) if len(s) > 8 else 0.0,
                )
            m = tables.n_inputs
            if (
                tables.succ.shape != (N_CLASSES, grid.npsi, m, 4)
                or planes.shape[:3] != (m, grid.npsi, (grid.ny + 63) // 64)
                or planes.shape[4] != grid.nx
                or viable.shape != (N_CLASSES, m, grid.npsi, (grid.ny + 63) // 64, grid.nx)
                or winning.shape[0] != m
                or (safe is not None and safe.shape != winning.shape)
            ):
                raise ControllerFileError(f"{str(path)!r}: arrays do not fit the grid and inputs")
            lattice = InputLattice.of(tables.inputs)
        except ControllerFileError:
            raise
        except (OSError, KeyError, ValueError, IndexError, TypeError) as err:
            raise ControllerFileError(f"cannot read controller {str(path)!r}: {err}") from err
        except SymbolicError as err:
            raise ControllerFileError(f"cannot read controller {str(path)!r}: {err}") from err
        return cls(tables, lattice, winning, planes, viable, pads, obstacles, stats, safe)
