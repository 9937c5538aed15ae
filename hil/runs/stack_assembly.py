"""The stack's composition root: the one place every backend assembles the full stack.

A simulated run (:mod:`hil.runs.sim_run`), the vessel over ROS 2 (:mod:`hil.runs.vessel_run`),
replay's stack re-run and the views build the runtime, its synthesizer and the scenario's
identity here, so they cannot drift apart.
"""

from __future__ import annotations

import math
from pathlib import Path

from hil.controllers.pid import PidGains
from hil.controllers.symbolic import Select, SymbolicProblem, Synthesizer, j_select, wait_slowest
from hil.core.arrays import FloatArray
from hil.runtime.assembly import EkfObserver, LayoutSolver, low_level_for
from hil.runtime.loop import Runtime, World
from hil.runtime.protocols import RunLog, SymbolicController
from hil.runtime.report_age import ReportAgeBudget
from hil.runtime.resynthesis import ResynthesisMode, Resynthesizer, Solve
from hil.runtime.settings import LoopConfig
from hil.scenarios import Scenario

__all__ = ["build_runtime", "default_start", "report_ages_of", "scenario_hash", "synthesizer_for"]


def default_start(scenario: Scenario) -> tuple[float, float, float]:
    """Return the paper's kind of start: right of the arena, lower half, bow up (+y)."""
    x1 = scenario.x_range_m[1]
    y0, y1 = scenario.y_range_m
    return (x1 - 0.75, y0 + 0.25 * (y1 - y0), math.pi / 2)


def scenario_hash(scenario: Scenario) -> str:
    """Return a short, stable hash of a scenario's content (:meth:`Scenario.digest`)."""
    return scenario.digest()


def build_runtime(
    scenario: Scenario, world: World, log: RunLog, loop: LoopConfig,
    synthesizer: Synthesizer, mode: ResynthesisMode, *,
    select: Select = j_select, wait_select: Select = wait_slowest,
    start_nu: FloatArray | None = None,
    solver: Solve[SymbolicController] | None = None,
    gains: PidGains | None = None,
    synthesis_latency_s: float = 0.0,
) -> Runtime:
    """Compose the full stack for `scenario` against `world`.

    Args:
        scenario: The docking problem.
        world: Clock and adapters of one backend.
        log: Where the run is recorded.
        loop: Loop timing and thresholds.
        synthesizer: Holds the grid's abstraction tables.
        mode: Where re-synthesis runs.
        select: Choice among the safe inputs; the paper's cost J by default.
        wait_select: Choice among the safety controller's inputs while docking is not
            winning; the slowest by J by default.
        start_nu: Body velocity (3,) the EKF starts from; None at rest.
        solver: (Layout, report age) -> controller; a :class:`LayoutSolver` if None.
        gains: Velocity-PID gains; None: the shipped ones.
        synthesis_latency_s: Inline: each synthesis takes this long on the world's clock.

    Raises:
        ValueError: The loop's decision period is not the scenario's tau (every budget
            and the controller's guarantee are for decisions every tau).
    """
    if loop.decision_period_s != scenario.tau_s:
        raise ValueError(
            f"[loop] decision_period_s = {loop.decision_period_s:g} s, but scenario "
            f"{scenario.name!r} was abstracted for tau_s = {scenario.tau_s:g} s: the "
            "controller's guarantee holds for decisions every tau; set them equal"
        )
    layout_solver = LayoutSolver(scenario, synthesizer)
    solve = solver if solver is not None else layout_solver
    # In a thread a new layout's controller is put in force as soon as it covers the
    # vessel's state (the solve's early stop), before the full solve ends.
    resynthesizer: Resynthesizer[SymbolicController] = Resynthesizer(
        solve, mode, stages=layout_solver.stages if solver is None else None,
        latency_s=synthesis_latency_s, clock=world.clock.now_ns)
    observer = EkfObserver(
        start_nu=start_nu, estimation_bound_m=scenario.transient.estimation_position_m
    )
    return Runtime(world, observer, low_level_for(loop.loop_hz, gains),
                   resynthesizer, select, log, loop, scenario_hash(scenario),
                   estimation_position_m=scenario.transient.estimation_position_m,
                   report_ages=report_ages_of(scenario), wait_select=wait_select)


def report_ages_of(scenario: Scenario) -> ReportAgeBudget:
    """Return the report-age budget of `scenario`'s ``[obstacle_motion]`` (stated or measured)."""
    tracking = scenario.tracking
    return ReportAgeBudget(
        tracking.max_report_age_s, scenario.tracks_obstacles, tracking.measures_report_age
    )


def synthesizer_for(
    scenario: Scenario, cache_dir: Path | None = None, threads: int = 1,
    prepare_outputs: bool = False,
) -> Synthesizer:
    """Return a synthesizer holding the scenario grid's tables (from the disk cache).

    Its solves read and write the solved-controller store under the same folder.

    Args:
        scenario: Whose grid, inputs and budget.
        cache_dir: Table cache folder (default: the package's).
        threads: Kernel threads per solve (see :class:`Synthesizer`).
        prepare_outputs: Map the next solve's result arrays between solves (the vessel's
            re-synthesis in a thread; see :class:`Synthesizer`).
    """
    tables, _ = SymbolicProblem.from_scenario(scenario).tables(cache_dir=cache_dir)
    return Synthesizer(tables, threads=threads, cache_dir=cache_dir,
                       prepare_outputs=prepare_outputs)
