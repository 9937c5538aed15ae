"""Shared fixtures: the coarse scenario, its tables (cached in a temporary folder), controller."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.controllers.symbolic import Controller, SymbolicProblem, Synthesizer, Tables, tables_for
from hil.scenarios import Scenario, TrackingMargin, load_scenario


@pytest.fixture(scope="session")
def cache_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("symbolic-cache")


@pytest.fixture(scope="session")
def coarse() -> Scenario:
    # The known answers below are the paper's abstraction (margin zero); the packaged
    # scenario carries the low level's margin, which tests that need it set themselves.
    return load_scenario("coarse").with_margin(TrackingMargin())


@pytest.fixture(scope="session")
def coarse_problem(coarse: Scenario) -> SymbolicProblem:
    return SymbolicProblem.from_scenario(coarse)


@pytest.fixture(scope="session")
def coarse_tables(coarse_problem: SymbolicProblem, cache_dir: Path) -> Tables:
    p = coarse_problem
    tables, _ = tables_for(p.grid, p.inputs, p.tau_s, p.margin, cache_dir=cache_dir)
    return tables


@pytest.fixture(scope="session")
def coarse_controller(coarse_problem: SymbolicProblem, coarse_tables: Tables) -> Controller:
    return Synthesizer(coarse_tables).solve_sets(coarse_problem.obstacles, coarse_problem.target)
