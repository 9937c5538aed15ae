"""One decision query: what `SymbolicAdapter.decide` answers, checked against its parts.

At every cell of the tiny problem, with the rest and another reference in force, for
first and later decisions: the value, the inputs listed, the choice (J, or the slowest
by J against rest where the vessel waits) and its contract are what the controller's
separate questions answer; each listed input's successor value is the largest value of
its successor cells, taken here from the solved layers and the tables alone, below the
state's value for a later decision (the descent the guarantee rests on); and the
``slowest`` policy flies the input of the largest one.
"""

from __future__ import annotations

import math

import numpy as np

from hil.controllers.symbolic import (
    Controller,
    DecisionContract,
    Options,
    SymbolicAdapter,
    cost,
    j_select,
    wait_slowest,
)
from hil.runs.policies import policy


def _centre(controller: Controller, i: int, j: int, k: int) -> np.ndarray:
    g = controller.grid
    return np.array([g.x_min_m + (i + 0.5) * g.cell_x_m, g.y_min_m + (j + 0.5) * g.cell_y_m,
                     -np.pi + (k + 0.5) * 2 * np.pi / g.npsi])  # fmt: skip


def _largest_successor_value(
    controller: Controller, cell: tuple[int, int, int], u: int, cls: int
) -> int:
    """The largest value of input u's class-cls successor cells (-1 if one is losing)."""
    t = controller.tables
    g = controller.grid
    i, j, k = cell
    ox0, ox1, oy0, oy1 = (int(a) for a in t.succ[cls, k, u])
    h0, h1 = (int(a) for a in t.heading[cls, u])
    layer = controller.layer_values(u)
    worst = 0
    for ox in range(ox0, ox1 + 1):
        for oy in range(oy0, oy1 + 1):
            for oh in range(h0, h1 + 1):
                ii, jj, kk = i + ox, j + oy, (k + oh) % g.npsi
                if not (0 <= ii < g.nx and 0 <= jj < g.ny) or layer[ii, jj, kk] < 0:
                    return -1
                worst = max(worst, int(layer[ii, jj, kk]))
    return worst


def test_one_decision_answers_what_the_separate_questions_do(controller: Controller) -> None:
    adapter = SymbolicAdapter(controller)
    g = controller.grid
    rest = controller.rest_index
    other = int(controller.lattice.neighbours[rest, 0])
    previous = np.array([0.05, 0.0, 0.0])
    decided = descended = 0
    rng = np.random.default_rng(4)
    anywhere = np.argwhere(np.ones(g.shape, dtype=bool))
    winning = np.argwhere(controller.values > 0)
    sample = np.concatenate([anywhere[rng.choice(len(anywhere), 200, replace=False)],
                             winning[rng.choice(len(winning), 200, replace=False)]])
    for row in sample:
        cell = (int(row[0]), int(row[1]), int(row[2]))
        state = _centre(controller, *cell)
        for reference in (rest, other):
            for first in (False, True):
                a = adapter.decide(state, reference, first, previous)
                assert a.value == controller.decision_value(state, reference, first)
                expected = controller.decide_at(cell, reference, first)
                np.testing.assert_array_equal(a.inputs, expected.inputs)
                assert a.staying == expected.staying
                if a.value == 0.0 or a.inputs.size == 0:
                    assert a.chosen == -1
                    assert a.contract is None
                    continue
                rows = controller.inputs[a.inputs]
                against = np.zeros(3) if a.staying else previous
                assert a.chosen == int(a.inputs[np.argmin(cost(rows, against))])
                want = DecisionContract.of(controller, cell, a.chosen, reference, first,
                                           a.staying)  # fmt: skip
                assert a.contract is not None
                assert (a.contract.cell, a.contract.input_index, a.contract.budget_class,
                        a.contract.value) == (want.cell, want.input_index, want.budget_class,
                                              want.value)  # fmt: skip
                if a.staying:
                    continue
                decided += 1
                values = controller.decide_at(cell, reference, first).successor_values
                for u, got in zip(a.inputs, values, strict=True):
                    cls = 2 if first else (0 if int(u) == reference else 1)
                    assert got == _largest_successor_value(controller, cell, int(u), cls)
                    if not first:
                        assert got < a.value
                        descended += 1
    assert decided > 200
    assert descended > 200


def test_slowest_flies_the_input_of_the_largest_successor_value(controller: Controller) -> None:
    adapter = SymbolicAdapter(controller)
    rest = controller.rest_index
    slowest = policy("slowest", 0, np.array([0.05, 0.05, 0.1]))
    seen = 0
    for row in np.argwhere(controller.values > 2):
        cell = (int(row[0]), int(row[1]), int(row[2]))
        state = _centre(controller, *cell)
        a = adapter.decide(state, rest, False, np.zeros(3), slowest, wait_slowest)
        if a.inputs.size < 2:
            continue
        values = controller.decide_at(cell, rest).successor_values
        assert a.chosen == int(a.inputs[int(np.argmax(values))])
        j = adapter.decide(state, rest, False, np.zeros(3), j_select, wait_slowest)
        seen += int(a.chosen != j.chosen)
        assert math.isfinite(a.value)
    assert seen > 0  # somewhere the slowest is not J's choice


def test_a_selection_sees_the_listed_inputs_as_options(controller: Controller) -> None:
    adapter = SymbolicAdapter(controller)
    rest = controller.rest_index
    i, j, k = (int(v) for v in np.argwhere(controller.values > 2)[0])
    state = _centre(controller, i, j, k)
    seen: list[Options] = []

    def spy(options: Options) -> int:
        seen.append(options)
        return len(options.inputs) - 1

    a = adapter.decide(state, rest, False, np.array([0.05, 0.0, 0.0]), spy, wait_slowest)
    (o,) = seen
    np.testing.assert_array_equal(o.indices, a.inputs)
    np.testing.assert_array_equal(o.inputs, controller.inputs[a.inputs])
    np.testing.assert_array_equal(o.state, state)
    np.testing.assert_array_equal(o.previous, [0.05, 0.0, 0.0])
    assert a.chosen == int(a.inputs[-1])
