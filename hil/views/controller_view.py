"""What the symbolic controller saw at each recorded decision, rebuilt from the log.

Two pictures per decision:

- the safe inputs as predicted arcs: the kinematic model with body velocities held
  for tau, in closed form (DESIGN.md): the position after t is
  ``p0 + R(psi0) d(nu, t)`` with ``d`` from
  :func:`hil.controllers.symbolic.abstraction.displacement`;
- the winning set at the decision's heading cell: the controller is synthesized
  again for the layout in force at the decision (the same grid, tables and
  inflation as the run, :class:`hil.runtime.assembly.LayoutSolver`), and the
  (nx, ny) slice at that heading cell of its value function V with the decision's
  reference in force (the game state is (cell, reference); a decision with no
  recorded reference gets the layer from rest). A regular decision's recorded value is
  the slice's value at its cell; a first decision's is not (it may choose a change
  the layer does not allow, see ``Controller.decision_value``).

Re-synthesis runs once per distinct layout, not per decision.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hil.bag.run_data import Layout, RunData
from hil.controllers.symbolic import Controller, Grid, SymbolicError
from hil.controllers.symbolic.abstraction import arc_poses
from hil.core.arrays import FloatArray
from hil.core.records import Decision
from hil.runs.stack_assembly import scenario_hash, synthesizer_for
from hil.runtime.assembly import LayoutSolver, obstacles_from_layout
from hil.scenarios import Scenario, ScenarioError, load_scenario, packaged_scenarios

I32Array = NDArray[np.int32]


def scenario_for(run: RunData) -> tuple[Scenario | None, str]:
    """Return the run's scenario and a note ("" when found as recorded).

    The scenario named in the log's metadata; failing that (a bare ``.mcap``
    split, a renamed file), the packaged scenario whose hash the decisions carry.
    """
    name = run.run.scenario_file if run.run is not None else ""
    problem = "the log names no scenario"
    if name:
        try:
            return load_scenario(name), ""
        except ScenarioError as err:
            problem = f"scenario {name!r} cannot be loaded ({err})"
    hashes = {d.scenario_hash for d in run.decisions} - {""}
    for candidate in packaged_scenarios():
        scenario = load_scenario(candidate)
        if scenario_hash(scenario) in hashes:
            return scenario, f"{problem}; using packaged scenario {candidate!r} (same hash)"
    return None, f"{problem}: arena, targets and winning set are left out"


def predicted_arcs(
    state: Sequence[float], inputs: FloatArray, tau_s: float, n_points: int = 16
) -> FloatArray:
    """Return the positions the kinematic model predicts over [0, tau] for each input.

    Args:
        state: Start pose (x m, y m, psi rad).
        inputs: Body velocities held for tau, shape (m, 3), rows (u m/s, v m/s, r rad/s).
        tau_s: Holding time (s).
        n_points: Points per arc (>= 2), evenly spaced in time from 0 to tau.

    Returns:
        Arena positions, shape (m, n_points, 2), indexed [input, time, (x, y)] in m.
    """
    t_s = np.linspace(0.0, tau_s, max(n_points, 2))
    out: FloatArray = arc_poses(np.asarray(state, dtype=np.float64), inputs, t_s)[..., :2]
    return out


def obstacle_names(scenario: Scenario | None, count: int) -> list[str]:
    """Return the names of `count` drawn obstacles: the scenario's, else O1, O2, ..."""
    if scenario is not None and len(scenario.obstacles) == count:
        return [o.name for o in scenario.obstacles]
    return [f"O{n + 1}" for n in range(count)]


def inflated_outlines(scenario: Scenario, layout: Layout) -> tuple[FloatArray, ...]:
    """Return the inflated obstacles of a layout, each shape (n, 2) in m.

    The recorded inflated polygons when the log holds them, else the layout's
    obstacles inflated the way the run's solver inflates them.
    """
    if layout.inflated:
        return layout.inflated
    obstacles = obstacles_from_layout(scenario, layout.as_obstacle_layout())
    return tuple(o.inflated.vertices() for o in obstacles)


@dataclass(frozen=True, slots=True)
class WinningSlice:
    """The value function at one heading cell.

    Attributes:
        grid: The controller's grid.
        heading_cell: Heading cell k of the slice.
        values: V[:, :, k] with input `reference_index` in force, shape (nx, ny)
            indexed [i, j]: steps of tau to the target, -1 outside the winning set.
        obstacles: Obstacle cells, shape (nx, ny) indexed [i, j].
        reference_index: Input-grid index of the reference in force (the layer).
    """

    grid: Grid
    heading_cell: int
    values: I32Array
    obstacles: NDArray[np.bool_]
    reference_index: int = -1

    @property
    def winning_cells(self) -> int:
        """Return the number of winning cells in the slice."""
        return int(np.count_nonzero(self.values >= 0))


@dataclass(frozen=True, slots=True)
class ControllerView:
    """The controller's view at every decision of a run.

    Attributes:
        slices: One winning-set slice per decision (None where none could be made).
        note: Why slices are missing ("" when all were made).
    """

    slices: tuple[WinningSlice | None, ...]
    note: str = ""


def heading_cell(grid: Grid, decision: Decision) -> int | None:
    """Return the heading cell of a decision (from its flat cell index, else its state)."""
    if 0 <= decision.cell < grid.n_cells:
        return decision.cell % grid.npsi
    cell = grid.cell_of(decision.state)
    return None if cell is None else cell[2]


def layer_slice(controller: Controller, reference: int, k: int) -> WinningSlice:
    """Return the slice of V at heading cell `k` with input `reference` in force.

    `reference` outside the input grid (-1: not recorded) gives the layer from rest.
    """
    g = controller.grid
    if not 0 <= reference < len(controller.inputs):
        reference = controller.rest_index
    i, j = np.meshgrid(np.arange(g.nx), np.arange(g.ny), indexing="ij")
    flat = controller.values_at(reference, i.ravel(), j.ravel(), np.full(i.size, k))
    values = flat.reshape(g.nx, g.ny).astype(np.int32)
    return WinningSlice(g, k, values, controller.obstacles, reference)


def controller_view(
    run: RunData, scenario: Scenario, budget_s: float | None = None
) -> ControllerView:
    """Re-synthesize the run's controller per layout and slice V at each decision.

    The slice is the layer of the decision's reference in force (:func:`layer_slice`).

    Args:
        run: The recorded run.
        scenario: The scenario the run used (its grid, inputs, inflation, target).
        budget_s: Wall time allowed for re-synthesis (s); once spent, decisions
            under a layout not yet solved get no slice (a run whose obstacles
            move all the time has a layout per decision). None: no limit. The
            first layout is always solved.

    Returns:
        The slices; a decision without a layout, outside the grid, whose layout
        has no winning set, or past the budget gets None, and the note says why.
    """
    if not run.decisions:
        return ControllerView(())
    notes: list[str] = []
    recorded = {d.scenario_hash for d in run.decisions} - {""}
    if recorded and scenario_hash(scenario) not in recorded:
        notes.append(
            f"scenario {scenario.name!r} has changed since the run (hash "
            f"{scenario_hash(scenario)!r}, log {sorted(recorded)!r}): the winning set may differ"
        )
    start = time.perf_counter()
    solver = LayoutSolver(scenario, synthesizer_for(scenario))
    controllers: dict[tuple[object, ...], Controller | None] = {}
    slices: list[WinningSlice | None] = []
    over_budget = 0
    for decision in run.decisions:
        layout = run.layout_at(decision.t_ns)
        if layout is None:
            slices.append(None)
            continue
        age = decision.report_age_s or scenario.tracking.max_report_age_s
        key = (tuple(layout.rectangles), age)
        spent = time.perf_counter() - start
        if key not in controllers and controllers and budget_s is not None and spent > budget_s:
            over_budget += 1
            slices.append(None)
            continue
        if key not in controllers:
            try:
                controllers[key] = solver(layout.as_obstacle_layout(), age).controller
            except SymbolicError as err:
                notes.append(f"layout at t={layout.t_ns} ns: {err}")
                controllers[key] = None
        controller = controllers[key]
        k = None if controller is None else heading_cell(controller.grid, decision)
        if controller is None or k is None:
            slices.append(None)
            continue
        slices.append(layer_slice(controller, decision.reference_index, k))
    if over_budget:
        notes.append(
            f"re-synthesis budget of {budget_s:g} s spent after {len(controllers)} layout(s): "
            f"no winning set at {over_budget} later decision(s)"
        )
    return ControllerView(tuple(slices), "; ".join(notes))
