"""The abstract reach-avoid problem: grid, inputs, timing, budget, hull and the sets."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from hil.controllers.symbolic.abstraction import Tables, tables_for
from hil.controllers.symbolic.grid import Grid, obstacle_mask, target_mask
from hil.controllers.symbolic.hull import free_masks
from hil.core.arrays import BoolArray, FloatArray
from hil.core.shapes import Rect, Shape
from hil.core.transient import LATE_S, TransientBudget
from hil.scenarios import Scenario

__all__ = ["SymbolicProblem"]

@dataclass(frozen=True, slots=True, eq=False)
class SymbolicProblem:
    """A reach-avoid problem on a grid, for a hull that moves as the budget allows.

    Attributes:
        grid: The state grid.
        inputs: Inputs (surge m/s, sway m/s, yaw rate rad/s), shape (m, 3).
        tau_s: Command period (s).
        budget: The closed loop's deviation from the exact arc, per class, and the
            estimate's error.
        obstacles: Real obstacles in (x, y); an obstacle that moves is grown by how far
            it may move while the controller relies on its report
            (:meth:`~hil.scenarios.Scenario.obstacle_reach`).
        inflation_m: The centre keeps this far from every (grown) obstacle (m), besides
            the hull never touching one (the paper's abstract obstacles).
        target: Abstract (deflated) target in (x, y).
        arena: The walls: the hull stays inside.
        hull_m: Hull (length, beam) (m), centred on the body origin.
        late_s: How late a command may come and stay covered (s).
        name: Where it came from.
    """

    grid: Grid
    inputs: FloatArray
    tau_s: float
    budget: TransientBudget
    obstacles: tuple[Shape, ...]
    inflation_m: float
    target: Shape
    arena: Rect
    hull_m: tuple[float, float]
    late_s: float = LATE_S
    name: str = ""

    @staticmethod
    def from_scenario(scenario: Scenario) -> SymbolicProblem:
        """Return the abstract problem of a scenario (moving obstacles grown by their reach)."""
        inflation = max((o.inflation_m for o in scenario.obstacles), default=0.0)
        return SymbolicProblem(
            grid=Grid.from_scenario(scenario),
            inputs=scenario.inputs(),
            tau_s=scenario.tau_s,
            budget=scenario.transient,
            obstacles=scenario.obstacle_reach(),
            inflation_m=inflation,
            target=scenario.abstract_target(),
            arena=scenario.arena,
            hull_m=(scenario.hull.length_m, scenario.hull.beam_m),
            name=scenario.name,
        )

    def tables(self, cache_dir: Path | None = None, use_cache: bool = True) -> tuple[Tables, bool]:
        """Return the problem's abstraction tables and whether they came from the cache."""
        return tables_for(
            self.grid,
            self.inputs,
            self.tau_s,
            self.budget,
            self.late_s,
            cache_dir=cache_dir,
            use_cache=use_cache,
        )

    def with_obstacles(self, obstacles: Sequence[Shape]) -> SymbolicProblem:
        """Return the same problem with another set of real obstacles."""
        return replace(self, obstacles=tuple(obstacles))

    def inflated_obstacle_mask(self) -> BoolArray:
        """Return (nx, ny) bool: cells touching an obstacle inflated by `inflation_m`."""
        return obstacle_mask(self.grid, [o.inflate(self.inflation_m) for o in self.obstacles])

    def free_masks(self, psi_lo: FloatArray, psi_hi: FloatArray) -> BoolArray:
        """Return (n, nx, ny) bool: cells free for the hull over each heading range (rad)."""
        return free_masks(
            self.grid,
            self.obstacles,
            self.arena,
            self.inflation_m,
            self.hull_m[0],
            self.hull_m[1],
            np.asarray(psi_lo, dtype=np.float64),
            np.asarray(psi_hi, dtype=np.float64),
        )

    def heading_free(self) -> BoolArray:
        """Return (nx, ny, npsi) bool: cells the hull may occupy at rest in each heading cell."""
        g = self.grid
        hp = g.heading_cell_rad
        lo = np.asarray(-np.pi + hp * np.arange(g.npsi), dtype=np.float64)
        out: BoolArray = np.ascontiguousarray(np.moveaxis(self.free_masks(lo, lo + hp), 0, -1))
        return out

    def target_cells(self, heading_free: BoolArray | None = None) -> BoolArray:
        """Return (nx, ny, npsi) bool: cells wholly inside the target, the hull free there."""
        g = self.grid
        free = self.heading_free() if heading_free is None else heading_free
        inside = target_mask(g, self.target, np.zeros((g.nx, g.ny), dtype=bool))
        out: BoolArray = np.ascontiguousarray(free & inside[:, :, None])
        return out
