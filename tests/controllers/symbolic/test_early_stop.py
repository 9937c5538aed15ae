"""The solve's early stop: a controller for the vessel's state before the fixed point.

The BFS joins states level by level; once the watched (cell, reference) joined at level
L, every state of value <= L is final. The early controller must hold exactly those, with
the full solve's values and, at every state it covers, the full solve's safe inputs (a
non-first decision there only looks at successors of lower values). Checked against the
full solve of a separate synthesizer, on every layer.
"""

from __future__ import annotations

import numpy as np
import pytest

from hil.controllers.symbolic import Controller, SymbolicProblem, Synthesizer, Tables, Watch

REFERENCES = (13, 0, 26)  # the tiny lattice's rest input (index 13) and two corners


def _watched_cells(controller: Controller, reference: int) -> list[tuple[int, int, int]]:
    """Return a cell of the lowest, a middle and the second highest value in a layer."""
    values = controller.layer_values(reference)
    levels = np.unique(values[values > 0])
    assert len(levels) >= 3, f"layer {reference} has too few values: {levels!r}"
    out = []
    for wanted in (levels[0], levels[len(levels) // 2], levels[-2]):
        found = np.argwhere(values == wanted)
        i, j, k = (int(x) for x in found[len(found) // 2])
        out.append((i, j, k))
    return out


@pytest.mark.parametrize("reference", REFERENCES)
def test_early_controller_holds_the_full_solve_below_the_vessels_value(
    problem: SymbolicProblem, tables: Tables, controller: Controller, reference: int
) -> None:
    m = tables.n_inputs
    for cell in _watched_cells(controller, reference):
        value = controller.cell_value(cell, reference)
        solver = Synthesizer(tables, memo=False, use_cache=False)
        stages = list(solver.solve_stages(problem, Watch(cell, reference)))
        assert [c.stats.complete for c in stages] == [False, True]
        early, full = stages
        assert early.stats.levels == value  # stopped right after the vessel's level
        assert early.cell_value(cell, reference) == value
        assert full.stats.levels == controller.stats.levels
        for p in range(m):
            truth = controller.layer_values(p)
            np.testing.assert_array_equal(full.layer_values(p), truth)
            np.testing.assert_array_equal(
                early.layer_values(p), np.where(truth <= value, truth, -1)
            )
        # Where it covers the state, a decision is the full solve's: same safe inputs.
        covered = np.argwhere(
            (controller.layer_values(reference) >= 1)
            & (controller.layer_values(reference) <= value)
        )
        for i, j, k in covered[:: max(len(covered) // 60, 1)]:
            c = (int(i), int(j), int(k))
            np.testing.assert_array_equal(
                early.safe_input_indices_at(c, reference),
                controller.safe_input_indices_at(c, reference),
            )


def test_a_state_in_the_target_is_covered_at_once_and_a_losing_one_never(
    problem: SymbolicProblem, tables: Tables, controller: Controller
) -> None:
    values = controller.values
    rest = controller.rest_index
    for wanted, expected in ((0, [False, True]), (-1, [True])):
        i, j, k = (int(x) for x in np.argwhere(values == wanted)[0])
        solver = Synthesizer(tables, memo=False, use_cache=False)
        stages = list(solver.solve_stages(problem, Watch((i, j, k), rest)))
        assert [c.stats.complete for c in stages] == expected
        np.testing.assert_array_equal(stages[-1].values, values)
        if wanted == 0:  # the goal alone, before any level ran
            assert stages[0].stats.levels == 0
            np.testing.assert_array_equal(stages[0].values, np.where(values == 0, 0, -1))


def test_prepared_outputs_give_the_same_controllers_and_keep_each_early_copy(
    problem: SymbolicProblem, tables: Tables, controller: Controller
) -> None:
    """A synthesizer that maps the next solve's arrays between solves (the vessel's).

    Three staged solves in a row on one synthesizer: each on prepared arrays after the
    first. Every controller equals a fresh synthesizer's, and an early controller's bits
    stay those of its level while the solve goes on and after the next solve (its copy is
    its own, not an array a later solve writes into).
    """
    rest = controller.rest_index
    cell = _watched_cells(controller, rest)[1]
    value = controller.cell_value(cell, rest)
    prepared = Synthesizer(tables, memo=False, use_cache=False, prepare_outputs=True)
    kept: list[tuple[Controller, Controller, np.ndarray]] = []
    for _ in range(3):
        early, full = prepared.solve_stages(problem, Watch(cell, rest))
        kept.append((early, full, early.winning_words.copy()))
    for early, full, bits in kept:
        assert not early.stats.complete
        assert full.stats.complete
        np.testing.assert_array_equal(early.winning_words, bits)
        np.testing.assert_array_equal(full.winning_words, controller.winning_words)
        np.testing.assert_array_equal(full.value_planes, controller.value_planes)
        np.testing.assert_array_equal(
            early.values, np.where(controller.values <= value, controller.values, -1))
        assert early.stats.winning_cells == int((early.values >= 0).sum())
    # Every solve got arrays of its own.
    arrays = [id(c.winning_words) for e, f, _ in kept for c in (e, f)]
    assert len(set(arrays)) == len(arrays)
