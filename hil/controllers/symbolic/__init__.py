"""Symbolic (finite-abstraction) reach-avoid controller: grid -> abstraction -> synthesis.

Imports go one way, as in SCOTS v0.2: grid and problem, abstraction (offset tables,
cached on disk), sweep (compiled fixed point), synthesis (one call per obstacle layout),
controller (value function and safe-input lookup), contract (what one decision
assumed, and judges of poses against it), selection (the paper's cost J), decide (one
decision asked once: the rule the vessel and the replay take);
reference holds the dense numpy solver used as baseline and second opinion.

Typical use::

    problem = SymbolicProblem.from_scenario(load_scenario("paper"))
    controller = synthesize(problem)                  # tables built once, then cached
    sigma = select(controller.safe_inputs(state), previous)
    # new obstacle layout, same tables, e.g. from a background thread:
    synthesizer = Synthesizer(controller.tables, threads=1)
    controller = synthesizer.solve_problem(moved)
"""

from hil.controllers.symbolic.abstraction import Tables, build_tables, default_cache_dir, tables_for
from hil.controllers.symbolic.contract import DecisionContract, cells_of
from hil.controllers.symbolic.controller import Controller, SynthesisStats
from hil.controllers.symbolic.decide import (
    Answer,
    Options,
    Select,
    SymbolicAdapter,
    j_select,
    wait_slowest,
)
from hil.controllers.symbolic.errors import (
    ControllerFileError,
    EmptyInputSetError,
    GridError,
    NoWinningSetError,
    SymbolicError,
)
from hil.controllers.symbolic.grid import Grid, obstacle_mask, target_mask
from hil.controllers.symbolic.hull import free_masks, hull_half_extents, target_cells
from hil.controllers.symbolic.problem import SymbolicProblem
from hil.controllers.symbolic.selection import cost, select
from hil.controllers.symbolic.sources import ControllerSources
from hil.controllers.symbolic.synthesis import Synthesizer, Watch, synthesize

__all__ = [
    "Answer",
    "Controller",
    "ControllerFileError",
    "ControllerSources",
    "DecisionContract",
    "EmptyInputSetError",
    "Grid",
    "GridError",
    "NoWinningSetError",
    "Options",
    "Select",
    "SymbolicAdapter",
    "SymbolicError",
    "SymbolicProblem",
    "SynthesisStats",
    "Synthesizer",
    "Tables",
    "Watch",
    "build_tables",
    "cells_of",
    "cost",
    "default_cache_dir",
    "free_masks",
    "hull_half_extents",
    "j_select",
    "obstacle_mask",
    "select",
    "synthesize",
    "tables_for",
    "target_cells",
    "target_mask",
    "wait_slowest",
]
