"""Small symbolic problems built directly (not from a packaged scenario), and exact flows.

The packaged scenarios may change resolution and have no winning set under a realistic
budget, so the tests build their own: a 30 x 20 x 24 grid over a 3 m x 2 m arena, 27
inputs (a full lattice over surge, sway and yaw rate), one obstacle, a target on the
left, and either a realistic budget or the zero one (exact tracking and estimation).

Also here: the exact kinematic flow in closed form (independent of the abstraction's
`displacement`), and independent re-computations from the tables alone (tube freeness,
successor cells) that the tests compare the solver and the controller against.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic import SymbolicProblem, Tables
from hil.controllers.symbolic.grid import Grid
from hil.controllers.symbolic.lattice import InputLattice
from hil.core.shapes import Rect, Shape
from hil.core.transient import TransientBudget

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

HULL = (0.3, 0.1)
ARENA = Rect(-1.5, 1.5, -1.0, 1.0)
OBSTACLE = Rect(0.2, 0.4, -1.0, 0.1)
INFLATION = 0.2
TARGET = Rect(-1.3, -0.7, -0.3, 0.5)
GRID = Grid(-1.5, -1.0, 0.1, 0.1, 30, 20, 24)
TAU_S = 2.0
LATE_S = 0.1
AXES = (np.array([0.0, 0.05, 0.1]), np.array([-0.05, 0.0, 0.05]), np.array([-0.1, 0.0, 0.1]))


def inputs(axes: tuple[FloatArray, FloatArray, FloatArray] = AXES) -> FloatArray:
    """Return the full input lattice over the axes, in C order (surge, sway, yaw rate)."""
    return np.array(list(itertools.product(*axes)), dtype=np.float64)


def envelope_budget(
    env: FloatArray, estimation_m: float, estimation_rad: float, speed_mps: float = 0.25
) -> TransientBudget:
    """Return a budget whose deviation bounds follow from velocity-error envelopes.

    env has shape (n_classes, 9, 3) (0.25-s bins over tau + late). A flight whose body
    velocity is off the input by at most env[c, bin] per axis, at a speed of at most
    `speed_mps`, strays from the exact arc by at most rho(t) = int |e_lin| + speed int
    theta and theta(t) = int |e_r| (|R(a) - R(b)| <= |a - b|): the tests fly such errors,
    so the bounds hold for them by construction, independently of how the library
    measured its own budgets.
    """
    bin_s = 0.25
    n_bins = env.shape[1]
    fine = np.linspace(0.0, n_bins * bin_s, n_bins * 200 + 1)
    dt = fine[1] - fine[0]
    b = np.minimum((fine[:-1] / bin_s).astype(int), n_bins - 1)
    position = np.zeros((env.shape[0], n_bins))
    heading = np.zeros((env.shape[0], n_bins))
    for c in range(env.shape[0]):
        theta = np.concatenate([[0.0], np.cumsum(env[c, b, 2] * dt)])
        lin = np.concatenate([[0.0], np.cumsum(np.hypot(env[c, b, 0], env[c, b, 1]) * dt)])
        rot = np.concatenate([[0.0], np.cumsum(speed_mps * theta[1:] * dt)])
        ends = np.arange(1, n_bins + 1) * 200
        position[c] = lin[ends] + rot[ends] + 1e-6
        heading[c] = theta[ends] + 1e-6
    return TransientBudget(
        bin_s=bin_s,
        envelopes=env,
        position_m=position,
        heading_rad=heading,
        estimation_position_m=estimation_m,
        estimation_heading_rad=estimation_rad,
        source="test: bounds integrated from the envelopes",
    )


def budget(scale: float = 1.0) -> TransientBudget:
    """Return a realistic budget (test_game's), its envelopes and estimation scaled."""
    env = np.zeros((3, 9, 3))
    env[0] = [0.002, 0.002, 0.005]
    env[1, :3] = [0.015, 0.015, 0.03]
    env[1, 3:] = [0.003, 0.003, 0.008]
    env[2] = 1.2 * env[1]
    return envelope_budget(scale * env, 0.004 * scale, 0.004 * scale)


def zero_budget() -> TransientBudget:
    """Return the zero budget: exact tracking, exact estimate."""
    return TransientBudget.zero(TAU_S)


def problem(
    the_budget: TransientBudget | None = None,
    obstacles: tuple[Shape, ...] = (OBSTACLE,),
    *,
    grid: Grid = GRID,
    the_inputs: FloatArray | None = None,
    target: Shape = TARGET,
    arena: Rect = ARENA,
    tau_s: float = TAU_S,
    late_s: float = LATE_S,
) -> SymbolicProblem:
    """Return the tiny problem (realistic budget unless told)."""
    return SymbolicProblem(
        grid=grid,
        inputs=inputs() if the_inputs is None else the_inputs,
        tau_s=tau_s,
        budget=budget() if the_budget is None else the_budget,
        obstacles=obstacles,
        inflation_m=INFLATION,
        target=target,
        arena=arena,
        hull_m=HULL,
        late_s=late_s,
        name="tiny",
    )


def flat_free(problem: SymbolicProblem, tables: Tables) -> BoolArray:
    """Return the free masks of every heading range of the tables, (n_ranges, nx, ny)."""
    flat = tables.hull_psi.reshape(-1, 2)
    return problem.free_masks(flat[:, 0], flat[:, 1])


# ---------------------------------------------------------------------- exact flow


def flow(start: FloatArray, nu: FloatArray, t: FloatArray) -> FloatArray:
    """Exact poses holding nu from start: start (n, 3), nu (n, 3), t (T,) -> (n, T, 3).

    Integrates R(psi0 + r s) (u, v) ds in closed form.
    """
    x0, y0, psi0 = (start[:, c : c + 1] for c in range(3))
    u, v, r = (nu[:, c : c + 1] for c in range(3))
    tt = np.asarray(t, dtype=np.float64)[None, :]
    psi = psi0 + r * tt
    straight = np.abs(r) < 1e-12
    r_safe = np.where(straight, 1.0, r)
    sin_d = np.sin(psi) - np.sin(psi0)
    cos_d = np.cos(psi) - np.cos(psi0)
    x_curved = (u * sin_d + v * cos_d) / r_safe
    y_curved = (-u * cos_d + v * sin_d) / r_safe
    x_line = (u * np.cos(psi0) - v * np.sin(psi0)) * tt
    y_line = (u * np.sin(psi0) + v * np.cos(psi0)) * tt
    x = x0 + np.where(straight, x_line, x_curved)
    y = y0 + np.where(straight, y_line, y_curved)
    return np.stack([x, y, np.broadcast_to(psi, x.shape)], axis=-1)


def cells(grid: Grid, poses: FloatArray) -> tuple[IntArray, IntArray, IntArray]:
    """Quantize poses (..., 3) to unbounded (i, j) and wrapped k, each (...,)."""
    i = np.floor((poses[..., 0] - grid.x_min_m) / grid.cell_x_m).astype(np.int64)
    j = np.floor((poses[..., 1] - grid.y_min_m) / grid.cell_y_m).astype(np.int64)
    psi = np.mod(poses[..., 2] + math.pi, 2.0 * math.pi)
    k = np.minimum(np.floor(psi / grid.heading_cell_rad).astype(np.int64), grid.npsi - 1)
    return i, j, k


def points_in_cell(
    grid: Grid, cell: tuple[int, int, int], n: int, rng: np.random.Generator
) -> FloatArray:
    """Return n random poses of the cell, its corners (to within 1e-9 cells) first, (n, 3)."""
    lo, hi = grid.cell_bounds(*cell)
    frac = rng.random((n, 3))
    frac[:8] = np.array(list(itertools.product((1e-9, 1.0 - 1e-9), repeat=3)))[: min(n, 8)]
    out: FloatArray = lo + frac * (hi - lo)
    return out


# ---------------------------------------------------------------------- table twins


def tube_cells(tables: Tables, c: int, k: int, u: int) -> Iterator[tuple[int, int]]:
    """Yield the tube's (x, y) cell offsets of class c, heading cell k, input u."""
    for col in range(int(tables.tube_n[c, k, u])):
        lo, hi = (int(v) for v in tables.tube_y[c, k, u, col])
        for oy in range(lo, hi + 1):
            yield int(tables.tube_x0[c, k, u]) + col, oy


def tube_free(tables: Tables, free: BoolArray, c: int, cell: tuple[int, int, int], u: int) -> bool:
    """Return whether every tube cell is in the grid and free for the tube's heading range."""
    g = tables.grid
    i, j, k = cell
    h = int(tables.hull_range_index()[c, k, u])
    for ox, oy in tube_cells(tables, c, k, u):
        ii, jj = i + ox, j + oy
        if not (0 <= ii < g.nx and 0 <= jj < g.ny) or not free[h, ii, jj]:
            return False
    return True


def successor_cells(
    tables: Tables, c: int, cell: tuple[int, int, int], u: int
) -> list[tuple[int, int, int]]:
    """Return the successor cells (unbounded i, j; wrapped k) of class c."""
    i, j, k = cell
    npsi = tables.grid.npsi
    ox0, ox1, oy0, oy1 = (int(v) for v in tables.succ[c, k, u])
    ok0, ok1 = (int(v) for v in tables.heading[c, u])
    return [
        (i + ox, j + oy, (k + ok) % npsi)
        for ox in range(ox0, ox1 + 1)
        for oy in range(oy0, oy1 + 1)
        for ok in range(ok0, ok1 + 1)
    ]


def worst_successor(
    values: list[NDArray[np.int32]], u: int, succ: list[tuple[int, int, int]]
) -> int:
    """Return the largest value of the successors in layer u; -1 if one is losing or off-grid."""
    v = values[u]
    nx, ny, _ = v.shape
    worst = 0
    for a, b, kk in succ:
        if not (0 <= a < nx and 0 <= b < ny) or v[a, b, kk] < 0:
            return -1
        worst = max(worst, int(v[a, b, kk]))
    return worst


def candidates(lattice: InputLattice, p: int, first: bool) -> list[tuple[int, int]]:
    """Return (input, class) of the inputs allowed after p: p first, then its neighbours."""
    out = [(p, 2 if first else 0)]
    n = int(lattice.n_neighbours[p])
    out += [(int(u), 2 if first else 1) for u in lattice.neighbours[p, :n]]
    return out
