"""Shared fixtures: the tiny problem (tests.controllers.symbolic.tiny), its tables, controllers.

Tables are built without the disk cache; controllers are solved with the memo off, so
that no test sees another's controller object.
"""

from __future__ import annotations

import pytest

from hil.controllers.symbolic import Controller, SymbolicProblem, Synthesizer, Tables
from tests.controllers.symbolic import tiny


@pytest.fixture(scope="session")
def problem() -> SymbolicProblem:
    return tiny.problem()


@pytest.fixture(scope="session")
def tables(problem: SymbolicProblem) -> Tables:
    return problem.tables(use_cache=False)[0]


@pytest.fixture(scope="session")
def controller(problem: SymbolicProblem, tables: Tables) -> Controller:
    out = Synthesizer(tables, memo=False, use_cache=False).solve_problem(problem)
    assert out.has_winning_start
    return out


@pytest.fixture(scope="session")
def zero_problem() -> SymbolicProblem:
    return tiny.problem(tiny.zero_budget())


@pytest.fixture(scope="session")
def zero_tables(zero_problem: SymbolicProblem) -> Tables:
    return zero_problem.tables(use_cache=False)[0]


@pytest.fixture(scope="session")
def zero_controller(zero_problem: SymbolicProblem, zero_tables: Tables) -> Controller:
    out = Synthesizer(zero_tables, memo=False, use_cache=False).solve_problem(zero_problem)
    assert out.has_winning_start
    return out
