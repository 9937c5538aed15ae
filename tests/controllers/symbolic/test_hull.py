"""Hull-aware free cells: half-extents against sampling, masks against independent checks.

The independent checks never use the module's extents: hulls come from
`hull_footprint`, obstacles are tested by separating axes on vertices (and, for a few
poses, by `hil.core.shapes`), and the tight single-heading check sweeps the hull's own
vertices over the cell's corners.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.symbolic import Grid, GridError, obstacle_mask
from hil.controllers.symbolic.hull import (
    _clear_touching,
    free_masks,
    hull_half_extents,
    target_cells,
)
from hil.core.shapes import Polygon, Rect, Shape, convex_distance_m, shapes_overlap
from hil.scenarios import Obstacle, Scenario, load_scenario
from hil.scenarios.scenario import hull_footprint

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

L, B = 0.99, 0.31
HALF_DIAGONAL = math.hypot(L / 2, B / 2)
TOL_M = 1e-9  # the grid's slack: a hull may reach this far past a wall


def _sampled_extents(lo: float, hi: float, n: int = 200_001) -> tuple[float, float]:
    psi = np.linspace(lo, hi, n)
    c, s = np.abs(np.cos(psi)), np.abs(np.sin(psi))
    return float(np.max(L / 2 * c + B / 2 * s)), float(np.max(L / 2 * s + B / 2 * c))


RANGES = [
    (0.0, 0.0),
    (0.1, 0.5),
    (0.2, 0.4),  # holds atan2(B, L) = 0.3031
    (1.0, 1.2),
    (3.0, 3.4),  # wraps past +pi
    (-3.5, -2.9),  # wraps past -pi
    (2.8, 3.6),
    (-10.0, -9.5),  # unwrapped
    (1.5, 1.7),  # holds pi/2 (a kink of ex, the flat top of ey)
    (-0.7, 0.7),
    (0.0, math.pi),
    (-math.pi, math.pi),
    (0.0, 7.0),
]


@pytest.mark.parametrize(("lo", "hi"), RANGES)
def test_half_extents_match_dense_sampling(lo: float, hi: float) -> None:
    ex, ey = hull_half_extents(L, B, [lo], [hi])
    sx, sy = _sampled_extents(lo, hi)
    # Never below a sample (sound); above it only by the sampling's own error.
    assert ex[0] >= sx - 1e-12
    assert ey[0] >= sy - 1e-12
    assert ex[0] <= sx + 1e-9
    assert ey[0] <= sy + 1e-9


def test_half_extents_closed_forms() -> None:
    lo = np.array([0.0, math.pi / 2, math.pi, -math.pi, 0.0, -1.0])
    hi = np.array([0.0, math.pi / 2, math.pi, math.pi, 2 * math.pi, 5.0])
    ex, ey = hull_half_extents(L, B, lo, hi)
    np.testing.assert_allclose(ex[:3], [L / 2, B / 2, L / 2], rtol=0, atol=1e-15)
    np.testing.assert_allclose(ey[:3], [B / 2, L / 2, B / 2], rtol=0, atol=1e-15)
    assert ex[3:].tolist() == [HALF_DIAGONAL] * 3
    assert ey[3:].tolist() == [HALF_DIAGONAL] * 3
    # Vectorized over ranges, any shape (n,), including none.
    assert hull_half_extents(L, B, [], [])[0].shape == (0,)


def test_bad_input_is_refused() -> None:
    with pytest.raises(GridError, match="finite"):
        hull_half_extents(L, B, [0.0, math.nan], [1.0, 1.0])
    with pytest.raises(GridError, match="reversed"):
        hull_half_extents(L, B, [0.0, 0.5], [1.0, 0.4])
    with pytest.raises(GridError, match="1-D"):
        hull_half_extents(L, B, [0.0, 0.5], [1.0])
    with pytest.raises(GridError, match="hull size"):
        hull_half_extents(-L, B, [0.0], [1.0])
    grid = Grid(0.0, 0.0, 1.0, 1.0, 4, 3, 8)
    arena = Rect(0.0, 4.0, 0.0, 3.0)
    with pytest.raises(GridError, match="reversed"):
        free_masks(grid, [], arena, 0.5, L, B, [1.0], [0.0])
    with pytest.raises(GridError, match="finite"):
        free_masks(grid, [], arena, 0.5, L, B, [math.nan], [0.0])
    with pytest.raises(GridError, match="inflation"):
        free_masks(grid, [], arena, -0.1, L, B, [0.0], [0.0])
    with pytest.raises(GridError, match="2 inflations"):
        free_masks(grid, [Rect(1, 2, 1, 2)], arena, [0.1, 0.2], L, B, [0.0], [0.0])
    clockwise = Polygon(((0.0, 0.0), (0.0, 1.0), (1.0, 0.0)))
    with pytest.raises(GridError, match="convex"):
        free_masks(grid, [clockwise], arena, 0.5, L, B, [0.0], [0.0])
    with pytest.raises(GridError, match="shape"):
        target_cells(grid, arena, np.ones((2, 3, 3), dtype=bool))


# ---------------------------------------------------------------- independent geometry


def _axes(poly: FloatArray) -> FloatArray:
    """Unit edge normals of a polygon (m, 2) -> (m, 2)."""
    e = np.roll(poly, -1, axis=0) - poly
    n = np.stack([e[:, 1], -e[:, 0]], axis=1)
    out: FloatArray = n / np.linalg.norm(n, axis=1, keepdims=True)
    return out


def _gaps(hulls: FloatArray, obstacle: FloatArray) -> FloatArray:
    """Largest separating gap between each hull (P, 4, 2) and a convex polygon (m, 2) (m).

    Positive: apart; zero or negative: touching or overlapping (separating axis theorem
    over both shapes' edge normals).
    """
    best = np.full(hulls.shape[0], -np.inf)
    obstacle_axes = _axes(obstacle)
    for k in range(4):  # the hull's own normals, per pose
        e = hulls[:, (k + 1) % 4] - hulls[:, k]
        d = np.stack([e[:, 1], -e[:, 0]], axis=1)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        ph = np.einsum("pvc,pc->pv", hulls, d)
        po = obstacle @ d.T  # (m, P)
        gap = np.maximum(po.min(axis=0) - ph.max(axis=1), ph.min(axis=1) - po.max(axis=0))
        best = np.maximum(best, gap)
    for d in obstacle_axes:
        ph = hulls @ d
        po = obstacle @ d
        gap = np.maximum(po.min() - ph.max(axis=1), ph.min(axis=1) - po.max())
        best = np.maximum(best, gap)
    return best


def _outside(points: FloatArray, shape: Shape) -> BoolArray:
    """True where points (P, 2) lie outside the closed convex shape."""
    v = shape.vertices()
    n = _axes(v)
    c = np.sum(n * v, axis=1)
    out: BoolArray = np.any(points @ n.T > c[None, :], axis=1)
    return out


def _check_poses(
    sc: Scenario, centres: FloatArray, headings: FloatArray
) -> tuple[BoolArray, BoolArray, BoolArray]:
    """Per (centre, heading) pair: hull in arena, hull clear of obstacles, centre off inflated.

    centres (P, 2), headings (Q,) -> three bool arrays (P, Q).
    """
    arena = sc.arena
    in_arena = np.ones((len(centres), len(headings)), dtype=bool)
    clear = np.ones_like(in_arena)
    for q, psi in enumerate(headings):
        shape = hull_footprint(sc.hull, 0.0, 0.0, float(psi)).vertices()
        hulls = centres[:, None, :] + shape[None, :, :]
        in_arena[:, q] = (
            (hulls[..., 0].min(axis=1) >= arena.x_min_m - TOL_M)
            & (hulls[..., 0].max(axis=1) <= arena.x_max_m + TOL_M)
            & (hulls[..., 1].min(axis=1) >= arena.y_min_m - TOL_M)
            & (hulls[..., 1].max(axis=1) <= arena.y_max_m + TOL_M)
        )
        for o in sc.obstacles:
            clear[:, q] &= _gaps(hulls, o.shape.vertices()) > 0.0
    off = np.ones(len(centres), dtype=bool)
    for o in sc.obstacles:
        off &= _outside(centres, o.inflated)
    return in_arena, clear, np.repeat(off[:, None], len(headings), axis=1)


def _masks(sc: Scenario, lo: FloatArray, hi: FloatArray) -> BoolArray:
    grid = Grid.from_scenario(sc)
    return free_masks(
        grid,
        [o.shape for o in sc.obstacles],
        sc.arena,
        [o.inflation_m for o in sc.obstacles],
        sc.hull.length_m,
        sc.hull.beam_m,
        lo,
        hi,
    )


def _with_polygons(sc: Scenario) -> Scenario:
    """Return the scenario with O1, a tilted rectangle and a triangle as obstacles."""
    extra = (
        Obstacle("tilted", Polygon.rotated_rect((0.4, -1.6), (1.2, 0.4), 0.6), 0.5),
        Obstacle("triangle", Polygon(((2.6, 1.2), (3.6, 1.4), (3.0, 2.3))), 0.3),
    )
    return replace(sc, obstacles=(sc.obstacles[0], *extra))


def _scenario(name: str) -> Scenario:
    """Return the scenario a test name asks for: BASE[+polygons][@INFLATION_M].

    "+polygons" keeps O1 and adds a tilted rectangle and a triangle; "@0.1" sets every
    obstacle's inflation to 0.1 m: the scenarios' 0.5-m inflation covers the hull box on
    most headings, a small one leaves the hull test alone in charge.
    """
    name, _, inflation = name.partition("@")
    base, _, extra = name.partition("+")
    sc = load_scenario(base)
    if extra:
        sc = _with_polygons(sc)
    if inflation:
        sc = replace(
            sc, obstacles=tuple(replace(o, inflation_m=float(inflation)) for o in sc.obstacles)
        )
    return sc


def _ranges(npsi: int, pad_rad: float) -> tuple[FloatArray, FloatArray]:
    """Heading cells widened by pad_rad (a yaw swing), then a few odd ranges."""
    h = 2 * math.pi / npsi
    k = np.arange(npsi)
    lo = np.concatenate([-math.pi + k * h - pad_rad, [3.0, -3.6, 0.3, -math.pi, 1.0]])
    hi = np.concatenate([-math.pi + (k + 1) * h + pad_rad, [3.5, -2.9, 0.3, math.pi, 9.0]])
    return lo, hi


def _boundary(free: BoolArray) -> BoolArray:
    """Free cells with a blocked (or off-grid) 8-neighbour."""
    padded = np.pad(free, 1, constant_values=False)
    inner = np.ones_like(free)
    nx, ny = free.shape
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            inner &= padded[1 + di : 1 + di + nx, 1 + dj : 1 + dj + ny]
    out: BoolArray = free & ~inner
    return out


# ---------------------------------------------------------------------------- soundness


@pytest.mark.parametrize(
    "name",
    ["paper", "coarse", "coarse+polygons", "paper+polygons", "paper+polygons@0.1", "coarse@0"],
)
def test_free_cells_are_free_for_every_point_and_heading(name: str) -> None:
    sc = _scenario(name)
    grid = Grid.from_scenario(sc)
    lo, hi = _ranges(grid.npsi, 0.4)
    rng = np.random.default_rng(7)
    picks = np.concatenate([rng.choice(grid.npsi, 8, replace=False), grid.npsi + np.arange(5)])
    free = _masks(sc, lo[picks], hi[picks])
    # Corners, edge midpoints and the centre of the unit cell, then random points.
    unit = np.array([[a, b] for a in (0.0, 0.5, 1.0) for b in (0.0, 0.5, 1.0)])
    unit = np.concatenate([unit, rng.random((6, 2))])
    for r, h in enumerate(picks):
        cells = np.argwhere(_boundary(free[r]))
        others = np.argwhere(free[r])
        assert len(others), "no free cell to check"
        cells = np.concatenate(
            [
                cells[rng.choice(len(cells), min(60, len(cells)), replace=False)],
                others[rng.choice(len(others), 20)],
            ]
        )
        corner = np.array([grid.x_min_m, grid.y_min_m]) + cells * [grid.cell_x_m, grid.cell_y_m]
        centres = (corner[:, None, :] + unit[None] * [grid.cell_x_m, grid.cell_y_m]).reshape(-1, 2)
        headings = np.concatenate([[lo[h], hi[h]], rng.uniform(lo[h], hi[h], 8)])
        in_arena, clear, off = _check_poses(sc, centres, headings)
        assert in_arena.all(), f"range {h}: hull leaves the arena"
        assert clear.all(), f"range {h}: hull touches an obstacle"
        assert off.all(), f"range {h}: centre on an inflated obstacle"


def test_spot_check_with_shapes() -> None:
    """A few poses of free boundary cells, through hil.core.shapes itself."""
    sc = _with_polygons(load_scenario("coarse"))
    grid = Grid.from_scenario(sc)
    lo, hi = np.array([0.7]), np.array([1.3])
    free = _masks(sc, lo, hi)[0]
    rng = np.random.default_rng(3)
    cells = np.argwhere(_boundary(free))
    for i, j in cells[rng.choice(len(cells), 40, replace=False)]:
        for fx, fy, psi in ((0.0, 0.0, 0.7), (1.0, 1.0, 1.3), (1.0, 0.0, 1.0), (0.0, 1.0, 0.9)):
            x = grid.x_min_m + (i + fx) * grid.cell_x_m
            y = grid.y_min_m + (j + fy) * grid.cell_y_m
            hull = hull_footprint(sc.hull, x, y, psi)
            for o in sc.obstacles:
                assert not shapes_overlap(hull, o.shape)
                assert convex_distance_m(hull, o.shape) > 0.0


# ---------------------------------------------------------------------------- precision


def _tight(sc: Scenario, psi: float) -> BoolArray:
    """Exact free cells for one heading: the cell swept by the hull's own vertices."""
    grid = Grid.from_scenario(sc)
    hull = hull_footprint(sc.hull, 0.0, 0.0, psi).vertices()
    xs = grid.x_min_m + grid.cell_x_m * np.arange(grid.nx + 1)
    ys = grid.y_min_m + grid.cell_y_m * np.arange(grid.ny + 1)
    corners = np.stack(
        [
            np.stack(np.meshgrid(xs[a : a + grid.nx], ys[b : b + grid.ny], indexing="ij"), -1)
            for a in (0, 1)
            for b in (0, 1)
        ],
        axis=2,
    )  # (nx, ny, 4, 2)
    arena = sc.arena
    free = (
        (corners[..., 0].min(axis=2) + hull[:, 0].min() >= arena.x_min_m)
        & (corners[..., 0].max(axis=2) + hull[:, 0].max() <= arena.x_max_m)
        & (corners[..., 1].min(axis=2) + hull[:, 1].min() >= arena.y_min_m)
        & (corners[..., 1].max(axis=2) + hull[:, 1].max() <= arena.y_max_m)
    )
    # cell + hull is convex with edge normals x, y and the hull's; add the obstacle's.
    for o in sc.obstacles:
        v = o.shape.vertices()
        apart = np.zeros_like(free)
        for d in np.concatenate([np.eye(2), _axes(hull), _axes(v)]):
            pc = corners @ d  # (nx, ny, 4)
            ph, po = hull @ d, v @ d
            apart |= (pc.max(axis=2) + ph.max() < po.min()) | (po.max() < pc.min(axis=2) + ph.min())
        free &= apart
    out: BoolArray = free & ~obstacle_mask(grid, sc.inflated_obstacles())
    return out


@pytest.mark.parametrize("name", ["paper", "paper+polygons", "paper@0.1", "paper+polygons@0"])
def test_single_headings_are_exact(name: str) -> None:
    # For a range of width zero the masks are the exact free sets: equal, cell for cell,
    # to the tight sweep (so the fraction free at psi = 0 or pi/2 is the tight one, not
    # merely within a row per side).
    sc = _scenario(name)
    for psi in (0.0, math.pi / 2, math.pi, math.pi / 4, 0.3, -2.0):
        ours = _masks(sc, np.array([psi]), np.array([psi]))[0]
        tight = _tight(sc, psi)
        assert not (ours & ~tight).any(), psi
        assert not (tight & ~ours).any(), psi


@pytest.mark.parametrize("name", ["paper@0.1", "paper+polygons@0"])
def test_ranges_lie_within_the_sampled_free_set(name: str) -> None:
    # Over the whole grid: a cell free for a range is tight-free at each of 21 headings
    # of it (soundness), and the sampled free set (an upper bound on the exact one)
    # has at most 1 % more cells (measured with 61 headings: 26-95 cells of ~10,000 on
    # 0.7-0.9 rad ranges, 16-20 on a full turn). ANDing sub-range masks stays sound and
    # frees more cells of a 0.9-rad range.
    sc = _scenario(name)
    for lo, hi in ((0.3, 1.2), (-math.pi, math.pi)):
        sampled = np.ones((160, 120), dtype=bool)
        for psi in np.linspace(lo, hi, 21):
            sampled &= _tight(sc, psi)
        ours = _masks(sc, np.array([lo]), np.array([hi]))[0]
        assert not (ours & ~sampled).any()
        assert (sampled & ~ours).sum() <= 0.01 * sampled.sum()
        edges = np.linspace(lo, hi, 5)
        split = _masks(sc, edges[:-1], edges[1:]).all(axis=0)
        assert not (split & ~sampled).any()
        assert (split | ours).sum() > ours.sum() or hi - lo > math.pi


def _clear_touching_twin(
    out: BoolArray,
    xs: FloatArray,
    ys: FloatArray,
    spans: NDArray[np.int64],
    axes: FloatArray,
    reach: FloatArray,
    shadow: FloatArray,
    slack_m: float,
) -> None:
    cx = 0.5 * (xs[:-1] + xs[1:])
    cy = 0.5 * (ys[:-1] + ys[1:])
    for h, (i0, i1, j0, j1) in enumerate(spans):
        if i0 >= i1 or j0 >= j1:
            continue
        p = axes[h, :, 0, None, None] * cx[None, i0:i1, None] + (
            axes[h, :, 1, None, None] * cy[None, None, j0:j1]
        )
        r = reach[h, :, None, None]
        apart = (p - r > shadow[h, :, 1, None, None] + slack_m) | (
            p + r < shadow[h, :, 0, None, None] - slack_m
        )
        out[h, i0:i1, j0:j1] &= apart.any(axis=0)


def test_kernel_matches_numpy_twin() -> None:
    rng = np.random.default_rng(5)
    n, nx, ny, k = 7, 13, 11, 3
    xs = np.cumsum(rng.uniform(0.1, 0.3, nx + 1))
    ys = np.cumsum(rng.uniform(0.1, 0.3, ny + 1))
    start = rng.integers(0, 8, (n, 2))
    spans = np.stack(
        [start[:, 0], start[:, 0] + rng.integers(0, 6, n), start[:, 1], start[:, 1] + 4], axis=1
    ).astype(np.int64)
    angle = rng.uniform(-math.pi, math.pi, (n, k))
    axes = np.stack([np.cos(angle), np.sin(angle)], axis=2)
    reach = rng.uniform(0.0, 0.5, (n, k))
    mid = rng.uniform(-1.0, 3.0, (n, k))
    shadow = np.stack([mid - 0.3, mid + 0.3], axis=2)
    free = rng.random((n, nx, ny)) < 0.8
    got, want = free.copy(), free.copy()
    _clear_touching(got, xs, ys, spans, axes, reach, shadow, 1e-9)
    _clear_touching_twin(want, xs, ys, spans, axes, reach, shadow, 1e-9)
    np.testing.assert_array_equal(got, want)
    assert (got != free).any()  # the case clears something


def test_walls_are_exact_at_every_heading() -> None:
    sc = replace(load_scenario("paper"), obstacles=())
    psi = np.concatenate([np.linspace(-math.pi, math.pi, 121), [0.3031, 1.2677]])
    free = _masks(sc, psi, psi)
    for h, p in enumerate(psi):
        np.testing.assert_array_equal(free[h], _tight(sc, float(p)), err_msg=f"psi={p}")


def test_walls_block_by_the_extent_along_each_axis() -> None:
    grid = Grid(0.0, 0.0, 0.05, 0.05, 160, 120, 60)
    arena = Rect(0.0, 8.0, 0.0, 6.0)
    free = free_masks(grid, [], arena, 0.5, L, B, [0.0, math.pi / 2], [0.0, math.pi / 2])
    cols = free.sum(axis=2) > 0
    rows = free.sum(axis=1) > 0
    # psi = 0: ex = 0.495 -> 10 columns per side, ey = 0.155 -> 4 rows per side.
    assert (grid.nx - cols[0].sum(), grid.ny - rows[0].sum()) == (20, 8)
    # psi = pi/2: the walls block fewer x cells than y cells.
    assert (grid.nx - cols[1].sum(), grid.ny - rows[1].sum()) == (8, 20)


def test_point_hull_is_todays_obstacle_mask() -> None:
    sc = _with_polygons(load_scenario("paper"))
    grid = Grid.from_scenario(sc)
    shapes = [o.shape for o in sc.obstacles]
    free = free_masks(grid, shapes, sc.arena, 0.0, 0.0, 0.0, [0.0, 1.0], [0.0, 2.0])
    old = ~obstacle_mask(grid, shapes)
    assert (free == old[None]).all()


def test_a_full_turn_frees_fewest_cells() -> None:
    # The full turn's axes (x, y, the diagonals, the obstacle's normals, all with the
    # hull's half-diagonal) are among every range's, with at most that support.
    sc = _with_polygons(load_scenario("coarse"))
    lo = np.array([-math.pi, 0.2, 0.2, 0.5, 3.0, -9.0])
    hi = np.array([math.pi, 0.8, 0.5, 0.8, 3.5, -8.0])
    free = _masks(sc, lo, hi)
    assert not (free[0] & ~free[1:]).any()
    assert (free[1:].sum(axis=(1, 2)) > free[0].sum()).all()


def test_target_cells_are_inside_and_free() -> None:
    sc = load_scenario("paper")
    grid = Grid.from_scenario(sc)
    free = _masks(sc, np.array([0.0, math.pi / 2]), np.array([0.0, math.pi / 2]))
    target = target_cells(grid, sc.abstract_target(), free)
    assert target.shape == free.shape
    assert not (target & ~free).any()
    # T2 = [-3.25, -2.25] x [1.0, 2.0]: 20 x 20 cells; at psi = 0 the hull (ex = 0.495)
    # keeps the centre at x >= -3.005, so the first 5 columns go.
    assert target[1].sum() == 400
    assert target[0].sum() == 15 * 20
