"""A new layout's viable words from a prepared copy equal a fresh computation's."""

from __future__ import annotations

import numpy as np

from hil.controllers.symbolic import SymbolicProblem, Synthesizer
from hil.scenarios import load_scenario


def test_prepared_words_match_a_fresh_computation_and_leave_the_last_ones_alone() -> None:
    scenario = load_scenario("coarse")
    offsets = np.zeros((len(scenario.obstacles), 2))
    offsets[0, 1] = -0.1
    before = SymbolicProblem.from_scenario(scenario)
    after = SymbolicProblem.from_scenario(scenario.with_obstacles_moved(offsets))
    tables, _ = before.tables()
    synthesizer = Synthesizer(tables, memo=False, use_cache=False, prepare_outputs=True)
    viable = synthesizer._viable
    lo, hi = synthesizer._psi_lo, synthesizer._psi_hi
    last = viable.words(before.free_masks(lo, hi))
    kept = last.copy()
    viable.prepare()
    moved = viable.words(after.free_masks(lo, hi))
    fresh = Synthesizer(tables, memo=False, use_cache=False)._viable.words(
        after.free_masks(lo, hi))
    assert moved is not last
    assert not np.array_equal(moved, last)  # the layout's change reached the words
    np.testing.assert_array_equal(moved, fresh)
    np.testing.assert_array_equal(last, kept)  # a controller holding them sees no write
