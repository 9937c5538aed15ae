"""The grid's quantizer and the obstacle and target masks (touching, half inside, wholly inside)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.controllers.symbolic import Grid, GridError, obstacle_mask, target_mask
from hil.core.shapes import Polygon, Rect

GRID = Grid(0.0, 0.0, 1.0, 1.0, 4, 3, 8)


def test_cell_of_is_half_open_and_wraps_heading() -> None:
    assert GRID.cell_of((0.0, 0.0, -math.pi)) == (0, 0, 0)
    assert GRID.cell_of((0.999, 2.999, math.pi - 1e-9)) == (0, 2, 7)
    assert GRID.cell_of((1.0, 0.0, 0.0)) == (1, 0, 4)
    assert GRID.cell_of((1.0, 0.0, 2 * math.pi)) == (1, 0, 4)
    assert GRID.cell_of((4.0, 0.0, 0.0)) is None
    assert GRID.cell_of((0.0, -1e-12, 0.0)) is None


def test_cell_bounds_contain_their_points() -> None:
    lo, hi = GRID.cell_bounds(2, 1, 3)
    assert GRID.cell_of(0.5 * (lo + hi)) == (2, 1, 3)
    np.testing.assert_allclose(hi - lo, [1.0, 1.0, math.pi / 4])


def test_bad_grids_are_refused() -> None:
    with pytest.raises(GridError, match="at least one cell"):
        Grid(0.0, 0.0, 1.0, 1.0, 0, 3, 8)
    with pytest.raises(GridError, match="positive"):
        Grid(0.0, 0.0, -1.0, 1.0, 2, 3, 8)


def test_touching_and_half_inside_cells_are_obstacles() -> None:
    half = obstacle_mask(GRID, [Rect(1.5, 1.7, 1.2, 1.4)])  # strictly inside cell (1, 1)
    assert half.sum() == 1
    assert half[1, 1]
    edge = obstacle_mask(GRID, [Rect(2.0, 2.5, 0.2, 0.4)])  # touches cell (1, 0) along x = 2
    assert edge[1, 0]
    assert edge[2, 0]
    assert edge.sum() == 2
    corner = obstacle_mask(GRID, [Rect(3.0, 3.5, 2.0, 2.5)])  # touches (2, 1) at one corner
    assert corner[2, 1]
    assert corner.sum() == 4


def test_rotated_polygon_touches_only_cells_it_reaches() -> None:
    diamond = Polygon(((2.0, 0.6), (2.4, 1.0), (2.0, 1.4), (1.6, 1.0)))
    mask = obstacle_mask(GRID, [diamond])
    assert mask[1, 1]
    assert mask[2, 1]
    assert mask[1, 0]
    assert mask[2, 0]
    assert mask.sum() == 4  # its bounding box also reaches only these
    thin = Polygon.rotated_rect((2.0, 1.5), (3.0, 0.1), math.pi / 4)
    m = obstacle_mask(GRID, [thin])
    assert m[2, 1]
    assert m[1, 0]
    assert not m[0, 2]
    assert not m[3, 0]


def test_target_needs_whole_cells_clear_of_obstacles() -> None:
    free = np.zeros((4, 3), dtype=bool)
    inside = target_mask(GRID, Rect(0.5, 3.0, 0.0, 2.0), free)
    assert inside[1:3, 0:2].all()
    assert inside.sum() == 4
    blocked = free.copy()
    blocked[1, 1] = True
    assert not target_mask(GRID, Rect(0.5, 3.0, 0.0, 2.0), blocked)[1, 1]
    with pytest.raises(GridError, match="shape"):
        target_mask(GRID, Rect(0.0, 1.0, 0.0, 1.0), np.zeros((2, 2), dtype=bool))
