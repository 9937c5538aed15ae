"""Controllers kept up to a byte budget, the least recently used dropped first."""

from __future__ import annotations

from hil.controllers.symbolic import Synthesizer
from hil.runtime.controller_lru import ControllerLru
from tests.controllers.symbolic import tiny


def test_the_least_recently_used_go_first_and_the_newest_stays() -> None:
    problem = tiny.problem(tiny.zero_budget())
    tables, _ = problem.tables(use_cache=False)
    controller = Synthesizer(tables, memo=False, use_cache=False).solve_problem(problem)
    size = controller.nbytes
    assert size > controller.winning_words.nbytes
    kept: ControllerLru[str] = ControllerLru(budget=2 * size)
    kept.put("a", "A", controller)
    kept.put("b", "B", controller)
    assert kept.get("a") == "A"  # now the most recently used
    kept.put("c", "C", controller)
    assert kept.get("b") is None
    assert (kept.get("a"), kept.get("c"), len(kept)) == ("A", "C", 2)
    tight: ControllerLru[str] = ControllerLru(budget=1)
    tight.put("x", "X", controller)
    assert tight.get("x") == "X"  # the newest is kept whatever its size
    tight.put("y", "Y", controller)
    assert (tight.get("x"), tight.get("y")) == (None, "Y")
