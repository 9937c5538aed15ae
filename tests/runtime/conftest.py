"""The coarse scenario's controller, shared by the runtime tests that hold it fixed."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.controllers.symbolic import SymbolicAdapter
from hil.runs.stack_assembly import synthesizer_for
from hil.runtime.assembly import LayoutSolver, layout_from_scenario
from hil.scenarios import Scenario, load_scenario


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory) -> tuple[Scenario, SymbolicAdapter, Path]:
    """Return (coarse, its controller for the scenario's layout, a folder for the module)."""
    folder = tmp_path_factory.mktemp("runtime")
    scenario = load_scenario("coarse")
    synthesizer = synthesizer_for(scenario, folder / "tables")
    adapter = LayoutSolver(scenario, synthesizer)(layout_from_scenario(scenario))
    return scenario, adapter, folder
