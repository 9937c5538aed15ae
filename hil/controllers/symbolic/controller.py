"""The synthesized controller: the value function plus the offset tables.

Online it only looks up: the cell of the measured state (static quantizer, Reissig et
al. 2016), then every input whose swept tube is free and whose successors all have a
strictly smaller value. A state outside the grid or the winning set gets no input and
no exception, as in SCOTS' `StaticController` lookup but without throwing.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.abstraction import Tables
from hil.controllers.symbolic.errors import ControllerFileError
from hil.controllers.symbolic.grid import Grid
from hil.controllers.symbolic.kernels import safe_input_indices

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
I32Array = NDArray[np.int32]

__all__ = ["Controller", "SynthesisStats"]

_FORMAT = "hil-symbolic-controller-1"


@dataclass(frozen=True, slots=True)
class SynthesisStats:
    """Figures of one synthesis.

    Attributes:
        levels: Fixed-point iterations until no cell joined (the largest value).
        seconds: Wall time of the synthesis for this layout (s), tables excluded.
        winning_cells: Cells with a finite value, target included.
        free_cells: Obstacle-free cells (all headings).
        target_cells: Cells in the target (all headings).
        peak_bytes: Largest memory the synthesis held at once (bytes, traced).
        threads: Threads the kernel ran on.
    """

    levels: int
    seconds: float
    winning_cells: int
    free_cells: int
    target_cells: int
    peak_bytes: int = 0
    threads: int = 1

    @property
    def winning_fraction(self) -> float:
        """Return winning cells over free cells (0 with no free cell)."""
        return self.winning_cells / self.free_cells if self.free_cells else 0.0


class Controller:
    """A reach-avoid controller on a grid: V plus the abstraction's offset tables.

    Args:
        tables: The abstraction the controller was synthesized on.
        values: V, shape (nx, ny, npsi) indexed [i, j, k]: steps to the target, -1 losing.
        obstacles: Obstacle cells, shape (nx, ny) indexed [i, j].
        stats: Figures of the synthesis.
    """

    def __init__(
        self, tables: Tables, values: I32Array, obstacles: BoolArray, stats: SynthesisStats
    ) -> None:
        grid = tables.grid
        if values.shape != grid.shape or obstacles.shape != (grid.nx, grid.ny):
            raise ControllerFileError(
                f"value shape {values.shape!r} / obstacle shape {obstacles.shape!r} "
                f"do not match grid {grid.shape!r}"
            )
        self._tables = tables
        self._values = np.ascontiguousarray(values, dtype=np.int32)
        self._values.flags.writeable = False
        self._obstacles = np.ascontiguousarray(obstacles, dtype=bool)
        self._obstacles.flags.writeable = False
        prefix = np.zeros((grid.nx, grid.ny + 1), dtype=np.int32)
        np.cumsum(self._obstacles, axis=1, out=prefix[:, 1:])
        self._prefix = prefix
        self._out = np.empty(tables.n_inputs, dtype=np.int32)
        self.stats = stats

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
    def inputs(self) -> FloatArray:
        """Return all inputs, shape (m, 3)."""
        return self._tables.inputs

    @property
    def values(self) -> I32Array:
        """Return V (read-only), shape (nx, ny, npsi); -1 marks losing cells."""
        return self._values

    @property
    def obstacles(self) -> BoolArray:
        """Return the obstacle cells (read-only), shape (nx, ny)."""
        return self._obstacles

    @property
    def has_winning_start(self) -> bool:
        """Return True when some cell outside the target is winning."""
        return self.stats.winning_cells > self.stats.target_cells

    # ------------------------------------------------------------------ lookups

    def value(self, state: Iterable[float]) -> float:
        """Return V at the state's cell (steps of tau to the target); inf if not winning."""
        cell = self.grid.cell_of(state)
        if cell is None:
            return math.inf
        v = int(self._values[cell])
        return math.inf if v < 0 else float(v)

    def is_winning(self, state: Iterable[float]) -> bool:
        """Return True when the state lies in a winning cell (the target included)."""
        cell = self.grid.cell_of(state)
        return cell is not None and int(self._values[cell]) >= 0

    def safe_input_indices_at(self, cell: tuple[int, int, int]) -> I32Array:
        """Return the indices into :attr:`inputs` of the safe inputs at a cell, shape (n,)."""
        t = self._tables
        i, j, k = cell
        if not (0 <= i < self.grid.nx and 0 <= j < self.grid.ny and 0 <= k < self.grid.npsi):
            return np.empty(0, dtype=np.int32)
        n = safe_input_indices(
            self._values,
            self._prefix,
            t.succ,
            t.heading,
            t.tube_x0,
            t.tube_n,
            t.tube_y,
            i,
            j,
            k,
            self._out,
        )
        return self._out[:n].copy()

    def safe_inputs(self, state: Iterable[float]) -> FloatArray:
        """Return every safe input at the state, shape (n, 3) (u m/s, v m/s, r rad/s).

        Empty (shape (0, 3)) outside the grid, outside the winning set and in the target
        (the specification is met there; hold position).
        """
        cell = self.grid.cell_of(state)
        if cell is None:
            return np.empty((0, 3))
        out: FloatArray = self.inputs[self.safe_input_indices_at(cell)]
        return out

    # ------------------------------------------------------------------ files

    def save(self, path: str | Path) -> None:
        """Write the controller to a compressed .npz file (V as int16 where it fits)."""
        t = self._tables
        g = self.grid
        vmax = int(self._values.max())
        values = self._values.astype(np.int16) if vmax < np.iinfo(np.int16).max else self._values
        with Path(path).open("wb") as fh:
            np.savez_compressed(
                fh,
                format=np.array(_FORMAT),
                grid=np.array(
                    [g.x_min_m, g.y_min_m, g.cell_x_m, g.cell_y_m, g.nx, g.ny, g.npsi],
                    dtype=np.float64,
                ),
                inputs=t.inputs,
                tau_s=np.array(t.tau_s),
                margin=t.margin,
                succ=t.succ,
                heading=t.heading,
                tube_x0=t.tube_x0,
                tube_n=t.tube_n,
                tube_y=t.tube_y,
                key=np.array(t.key),
                values=values,
                obstacles=np.packbits(self._obstacles, axis=None),
                stats=np.array(list(asdict(self.stats).values()), dtype=np.float64),
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
                    float(gx[0]),
                    float(gx[1]),
                    float(gx[2]),
                    float(gx[3]),
                    int(gx[4]),
                    int(gx[5]),
                    int(gx[6]),
                )
                tables = Tables(
                    grid=grid,
                    inputs=np.ascontiguousarray(data["inputs"], dtype=np.float64),
                    tau_s=float(data["tau_s"]),
                    margin=data["margin"].astype(np.float64),
                    succ=data["succ"].astype(np.int32),
                    heading=data["heading"].astype(np.int32),
                    tube_x0=data["tube_x0"].astype(np.int32),
                    tube_n=data["tube_n"].astype(np.int32),
                    tube_y=data["tube_y"].astype(np.int32),
                    key=str(data["key"]),
                )
                values = data["values"].astype(np.int32)
                n_xy = grid.nx * grid.ny
                obstacles = (
                    np.unpackbits(data["obstacles"], count=n_xy)
                    .astype(bool)
                    .reshape(grid.nx, grid.ny)
                )
                s = data["stats"]
                stats = SynthesisStats(
                    int(s[0]), float(s[1]), int(s[2]), int(s[3]), int(s[4]), int(s[5]), int(s[6])
                )
        except ControllerFileError:
            raise
        except (OSError, KeyError, ValueError, IndexError, TypeError) as err:
            raise ControllerFileError(f"cannot read controller {str(path)!r}: {err}") from err
        if tables.succ.shape != (grid.npsi, tables.n_inputs, 4):
            raise ControllerFileError(
                f"{str(path)!r}: tables of shape {tables.succ.shape!r} do not fit the grid"
            )
        return cls(tables, values, obstacles, stats)
