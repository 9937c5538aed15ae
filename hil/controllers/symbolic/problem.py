"""The abstract reach-avoid problem: grid, inputs, tau, margin and the abstract sets."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.grid import Grid, obstacle_mask, target_mask
from hil.core.shapes import Shape
from hil.scenarios import Scenario

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

__all__ = ["SymbolicProblem"]


@dataclass(frozen=True, slots=True, eq=False)
class SymbolicProblem:
    """A reach-avoid problem on a grid.

    Attributes:
        grid: The state grid.
        inputs: Inputs (surge m/s, sway m/s, yaw rate rad/s), shape (m, 3).
        tau_s: Sampling time (s).
        margin: Tracking-error bound (surge, sway, yaw rate), shape (3,).
        obstacles: Abstract (inflated) obstacles in (x, y).
        target: Abstract (deflated) target in (x, y).
        name: Where it came from.
    """

    grid: Grid
    inputs: FloatArray
    tau_s: float
    margin: FloatArray
    obstacles: tuple[Shape, ...]
    target: Shape
    name: str = ""

    @staticmethod
    def from_scenario(scenario: Scenario) -> SymbolicProblem:
        """Return the abstract problem of a scenario (inflated obstacles, deflated target)."""
        return SymbolicProblem(
            grid=Grid.from_scenario(scenario),
            inputs=scenario.inputs(),
            tau_s=scenario.tau_s,
            margin=scenario.margin.as_array(),
            obstacles=scenario.inflated_obstacles(),
            target=scenario.abstract_target(),
            name=scenario.name,
        )

    def with_obstacles(self, obstacles: Sequence[Shape]) -> SymbolicProblem:
        """Return the same problem with another set of abstract obstacles."""
        return replace(self, obstacles=tuple(obstacles))

    def obstacle_mask(self) -> BoolArray:
        """Return (nx, ny) bool: cells touching an obstacle."""
        return obstacle_mask(self.grid, self.obstacles)

    def target_mask(self, obstacles: BoolArray | None = None) -> BoolArray:
        """Return (nx, ny) bool: obstacle-free cells wholly inside the target."""
        return target_mask(
            self.grid, self.target, self.obstacle_mask() if obstacles is None else obstacles
        )
