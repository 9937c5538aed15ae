"""The uniform state grid and the sets on it (obstacle and target masks).

Cells are half-open boxes: cell (i, j, k) holds x in [x_min + i hx, x_min + (i+1) hx),
y likewise and heading psi in [-pi + k hpsi, -pi + (k+1) hpsi) with hpsi = 2 pi / npsi.
The heading is periodic, so cell k = npsi - 1 borders cell 0. Obstacles and targets are
sets in (x, y) only (the abstract sets are inflated for the hull, PAPER.md), so their
masks have shape (nx, ny) and hold for every heading.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from hil.controllers.symbolic.errors import GridError
from hil.core.arrays import BoolArray, FloatArray
from hil.core.geometry import wrap_angle
from hil.core.shapes import Polygon, Rect, Shape
from hil.scenarios import Scenario

__all__ = ["Grid", "obstacle_mask", "target_mask"]

# Closed sets are compared with this slack (m): a cell within it of an obstacle counts as
# touching it; a cell sticking out of the target by less than it still counts as inside.
_SLACK_M = 1e-9


@dataclass(frozen=True, slots=True)
class Grid:
    """A uniform grid over [x_min, x_min + nx hx) x [y_min, y_min + ny hy) x [-pi, pi).

    Attributes:
        x_min_m: Lower x bound (m).
        y_min_m: Lower y bound (m).
        cell_x_m: Cell width in x (m).
        cell_y_m: Cell width in y (m).
        nx: Number of cells in x.
        ny: Number of cells in y.
        npsi: Number of heading cells dividing 2 pi.
    """

    x_min_m: float
    y_min_m: float
    cell_x_m: float
    cell_y_m: float
    nx: int
    ny: int
    npsi: int

    def __post_init__(self) -> None:
        if min(self.nx, self.ny, self.npsi) < 1:
            raise GridError(
                f"grid needs at least one cell per axis, got {(self.nx, self.ny, self.npsi)!r}"
            )
        if not (self.cell_x_m > 0.0 and self.cell_y_m > 0.0):
            raise GridError(f"cell widths must be positive, got {(self.cell_x_m, self.cell_y_m)!r}")

    @staticmethod
    def from_scenario(scenario: Scenario) -> Grid:
        """Return the grid a scenario asks for."""
        (x0, x1), (y0, y1) = scenario.x_range_m, scenario.y_range_m
        hx, hy = scenario.cell_m
        return Grid(
            x0, y0, hx, hy, round((x1 - x0) / hx), round((y1 - y0) / hy), scenario.heading_cells
        )

    @property
    def shape(self) -> tuple[int, int, int]:
        """Return (nx, ny, npsi)."""
        return (self.nx, self.ny, self.npsi)

    @property
    def n_cells(self) -> int:
        """Return the number of cells."""
        return self.nx * self.ny * self.npsi

    @property
    def heading_cell_rad(self) -> float:
        """Return the heading cell width 2 pi / npsi (rad)."""
        return 2.0 * math.pi / self.npsi

    @property
    def x_max_m(self) -> float:
        """Return the upper x bound (m)."""
        return self.x_min_m + self.nx * self.cell_x_m

    @property
    def y_max_m(self) -> float:
        """Return the upper y bound (m)."""
        return self.y_min_m + self.ny * self.cell_y_m

    def digest(self) -> str:
        """Return a short hash of the grid, for cache keys."""
        text = repr(
            (self.x_min_m, self.y_min_m, self.cell_x_m, self.cell_y_m, self.nx, self.ny, self.npsi)
        )
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def cell_of(self, state: Iterable[float]) -> tuple[int, int, int] | None:
        """Return the cell (i, j, k) holding state (x, y, psi), or None outside the grid.

        Non-finite states are outside. The heading is wrapped first, so any angle is fine.
        """
        x, y, psi = (float(v) for v in state)
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(psi)):
            return None
        i = math.floor((x - self.x_min_m) / self.cell_x_m)
        j = math.floor((y - self.y_min_m) / self.cell_y_m)
        if not (0 <= i < self.nx and 0 <= j < self.ny):
            return None
        k = math.floor((wrap_angle(psi) + math.pi) / self.heading_cell_rad)
        return i, j, min(max(k, 0), self.npsi - 1)

    def cell_bounds(self, i: int, j: int, k: int) -> FloatArray:
        """Return the cell's lower and upper corners, shape (2, 3): rows (lo, hi), (x, y, psi)."""
        lo = np.array(
            [
                self.x_min_m + i * self.cell_x_m,
                self.y_min_m + j * self.cell_y_m,
                -math.pi + k * self.heading_cell_rad,
            ]
        )
        widths = np.array([self.cell_x_m, self.cell_y_m, self.heading_cell_rad])
        return np.stack([lo, lo + widths])

    def _edges(self) -> tuple[FloatArray, FloatArray]:
        xs = np.asarray(self.x_min_m + self.cell_x_m * np.arange(self.nx + 1), dtype=np.float64)
        ys = np.asarray(self.y_min_m + self.cell_y_m * np.arange(self.ny + 1), dtype=np.float64)
        return xs, ys


def _polygon_halfplanes(vertices: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Return outward unit normals (n, 2) and offsets (n,) with poly = {p: N p <= c}."""
    edges = np.roll(vertices, -1, axis=0) - vertices
    normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return normals, np.sum(normals * vertices, axis=1)


def _touch(grid: Grid, shape: Shape) -> BoolArray:
    """Return (nx, ny): True where the closed cell touches the closed shape."""
    xs, ys = grid._edges()
    v = shape.vertices()
    near_x = (xs[:-1] <= v[:, 0].max() + _SLACK_M) & (xs[1:] >= v[:, 0].min() - _SLACK_M)
    near_y = (ys[:-1] <= v[:, 1].max() + _SLACK_M) & (ys[1:] >= v[:, 1].min() - _SLACK_M)
    mask: BoolArray = near_x[:, None] & near_y[None, :]
    if isinstance(shape, Rect):
        return mask
    # Separating axis theorem: the cell and a convex polygon are apart iff one of the
    # polygon's edge normals separates them (the x and y axes were tested above).
    cx = 0.5 * (xs[:-1] + xs[1:])[:, None]
    cy = 0.5 * (ys[:-1] + ys[1:])[None, :]
    normals, offsets = _polygon_halfplanes(v)
    for n, c in zip(normals, offsets, strict=True):
        radius = 0.5 * (grid.cell_x_m * abs(n[0]) + grid.cell_y_m * abs(n[1]))
        mask &= (n[0] * cx + n[1] * cy - radius) <= c + _SLACK_M
    return mask


def _inside(grid: Grid, shape: Shape) -> BoolArray:
    """Return (nx, ny): True where the whole closed cell lies in the closed shape."""
    xs, ys = grid._edges()
    if isinstance(shape, Rect):
        in_x = (xs[:-1] >= shape.x_min_m - _SLACK_M) & (xs[1:] <= shape.x_max_m + _SLACK_M)
        in_y = (ys[:-1] >= shape.y_min_m - _SLACK_M) & (ys[1:] <= shape.y_max_m + _SLACK_M)
        out: BoolArray = in_x[:, None] & in_y[None, :]
        return out
    assert isinstance(shape, Polygon)
    normals, offsets = _polygon_halfplanes(shape.vertices())
    mask: BoolArray = np.ones((grid.nx, grid.ny), dtype=bool)
    for n, c in zip(normals, offsets, strict=True):
        for cxs in (xs[:-1], xs[1:]):
            for cys in (ys[:-1], ys[1:]):
                mask &= (n[0] * cxs[:, None] + n[1] * cys[None, :]) <= c + _SLACK_M
    return mask


def obstacle_mask(grid: Grid, obstacles: Iterable[Shape]) -> BoolArray:
    """Return (nx, ny) bool, indexed [i, j]: True where a cell touches any obstacle."""
    mask = np.zeros((grid.nx, grid.ny), dtype=bool)
    for shape in obstacles:
        mask |= _touch(grid, shape)
    return mask


def target_mask(grid: Grid, target: Shape, obstacles: BoolArray) -> BoolArray:
    """Return (nx, ny) bool, indexed [i, j]: cells wholly inside the target and obstacle-free.

    Raises:
        GridError: `obstacles` has the wrong shape.
    """
    if obstacles.shape != (grid.nx, grid.ny):
        raise GridError(f"obstacle mask shape {obstacles.shape!r} != grid {(grid.nx, grid.ny)!r}")
    out: BoolArray = _inside(grid, target) & ~obstacles
    return out
