"""Scenarios (layer 1): the arena, obstacles, target, grids and budgets of a docking problem.

- :mod:`hil.scenarios.scenario`: the frozen scenario and its parts (inputs, hull,
  obstacles, target), hull footprint and clearances;
- :mod:`hil.scenarios.parse`: a scenario from parsed TOML, every key checked;
- :mod:`hil.scenarios.catalog`: the packaged scenarios by name (``paper.toml``,
  ``coarse.toml`` live beside it) or any TOML file by path;
- :mod:`hil.scenarios.errors`: :class:`ScenarioError`.

Shapes (:class:`~hil.core.shapes.Rect`, :class:`~hil.core.shapes.Polygon`) are in
:mod:`hil.core.shapes`. Imports only :mod:`hil.core`.
"""

from hil.scenarios.catalog import load_scenario, packaged_scenarios
from hil.scenarios.errors import ScenarioError
from hil.scenarios.parse import parse_scenario
from hil.scenarios.scenario import (
    Hull,
    InputAxis,
    Obstacle,
    ObstacleTracking,
    Scenario,
    SimulatedWorld,
    Target,
    check_start,
    hull_footprint,
)

__all__ = [
    "Hull",
    "InputAxis",
    "Obstacle",
    "ObstacleTracking",
    "Scenario",
    "ScenarioError",
    "SimulatedWorld",
    "Target",
    "check_start",
    "hull_footprint",
    "load_scenario",
    "packaged_scenarios",
    "parse_scenario",
]
