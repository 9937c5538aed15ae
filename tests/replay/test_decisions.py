"""The decisions check: a recorded decision taken again with the current code."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from hil.bag.run_data import load_run
from hil.controllers.symbolic import cost
from hil.core.records import Decision
from hil.replay.context import ReplayContext
from hil.replay.controllers import ScenarioCache
from hil.replay.decisions import (
    BOUNDARY_TOLERANCE,
    check_decisions,
    consistency,
    is_cost_tie,
    recompute,
    relied_on_stale_report,
)
from hil.replay.regression import Status
from hil.runs.stack_assembly import default_start
from hil.runtime.assembly import layout_from_scenario
from hil.scenarios import load_scenario


def test_recompute_mirrors_the_runtime_decision(caches: ScenarioCache) -> None:
    scenario = load_scenario("coarse")
    controller = caches.get(scenario)(layout_from_scenario(scenario))
    start = np.array(default_start(scenario))
    rest = controller.nearest_input(np.zeros(3))
    got = recompute(controller, start, np.zeros(3), rest, True)  # a run's first decision
    assert got.winning
    assert got.value > 0
    assert got.chosen in got.safe
    assert len(got.safe) >= 1
    # Every safe input is within one input-grid step per axis of the reference in force.
    steps = np.array([0.05, 0.05, 0.1])
    assert np.all(np.abs(controller.inputs[list(got.safe)]) <= steps + 1e-9)
    # The next decision, the chosen input in force: a regular one, its own safe set.
    on = recompute(controller, start, controller.inputs[got.chosen], got.chosen, False)
    assert on.winning
    assert on.chosen in on.safe
    reach = np.abs(controller.inputs[list(on.safe)] - controller.inputs[got.chosen])
    assert np.all(reach <= steps + 1e-9)
    in_target = recompute(controller, np.array([-2.75, 1.5, 0.0]), np.zeros(3), rest, True)
    assert (in_target.value, in_target.safe, in_target.chosen) == (0.0, (), -1)
    inside = recompute(controller, np.array([-1.0, 1.5, 0.0]), np.zeros(3), rest, True)  # in O2
    assert not inside.winning
    assert inside.chosen == -1


def test_recompute_waits_where_docking_is_lost_but_the_state_is_safe(
    caches: ScenarioCache,
) -> None:
    scenario = load_scenario("coarse")
    adapter = caches.get(scenario)(layout_from_scenario(scenario))
    c = adapter.controller
    rest = c.rest_index
    g = c.grid
    cells = np.argwhere(c.values < 0)  # (i, j, k) not winning from rest
    safe = c.safe_at(rest, cells[:, 0], cells[:, 1], cells[:, 2])
    assert safe.any(), "the coarse layout has safe states that cannot dock"
    i, j, k = (int(v) for v in cells[np.flatnonzero(safe)[0]])
    state = np.array([g.x_min_m + (i + 0.5) * g.cell_x_m, g.y_min_m + (j + 0.5) * g.cell_y_m,
                      -np.pi + (k + 0.5) * 2 * np.pi / g.npsi])  # fmt: skip
    assert g.cell_of(state) == (i, j, k)
    got = recompute(adapter, state, np.array([0.1, 0.0, 0.0]), rest, False)
    assert got.staying
    assert not got.winning
    listed = np.array(got.safe)
    np.testing.assert_array_equal(listed, np.sort(c.staying_input_indices_at((i, j, k), rest)))
    assert got.chosen == int(listed[np.argmin(cost(c.inputs[listed], np.zeros(3)))])  # J at rest
    recorded = Decision.from_arrays(
        1_000_000_000, state, adapter.locate(state), got.value, False, c.inputs[listed],
        listed, got.chosen, 1, "h", reference_index=rest,
    )  # fmt: skip
    assert recorded.staying
    assert consistency(recorded, c.inputs) == []


INPUTS = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.2, 0.0, 0.0], [0.1, 0.05, 0.0]])


def _decision(**changes: object) -> Decision:
    d = Decision.from_arrays(
        1_000_000_000, [1.0, 2.0, 0.5], 7, 4.0, True, INPUTS[[1, 2]], [1, 2], 2, 1, "h"
    )
    return dataclasses.replace(d, **changes)  # type: ignore[arg-type]


def test_a_decision_on_a_report_older_than_its_controller_was_solved_for_is_found() -> None:
    # Decided at 1 s on the report of 0.25 s: 0.75 s old.
    assert relied_on_stale_report(_decision(report_age_s=0.75, report_t_ns=250_000_000)) is None
    found = relied_on_stale_report(_decision(report_age_s=0.5, report_t_ns=250_000_000))
    assert found is not None
    assert "0.750 s old" in found.message
    assert "older than the 0.5 s its controller was solved for" in found.message
    assert relied_on_stale_report(_decision()) is None  # a log without the fields


def test_a_consistent_decision_has_no_problem() -> None:
    assert consistency(_decision(), INPUTS) == []
    assert consistency(_decision(), None) == []


@pytest.mark.parametrize(
    ("changes", "field", "text"),
    [
        ({"chosen_input": (0.1, 0.0, 0.0)}, "chosen_input", "chosen_index 2 is input-grid row"),
        ({"chosen_index": 3, "chosen_input": (0.1, 0.05, 0.0)}, "chosen_index", "not among"),
        ({"chosen_index": 9}, "chosen_index", "outside the input grid of 4"),
        (
            {"safe_inputs": ((0.1, 0.0, 0.0), (0.25, 0.0, 0.0))},
            "safe_inputs",
            "safe_inputs[1]: recorded [0.25, 0.0, 0.0] but input-grid row 2",
        ),
        ({"safe_input_indices": (2, 2)}, "safe_input_indices", "listed twice"),
        ({"winning": False}, "winning", "winning: recorded False but value 4.0"),
        ({"chosen_index": -1}, "chosen_index", "-1 (none) although 2 safe inputs"),
        ({"value": 0.0}, "safe_input_indices", "recorded at value 0.0"),
        (
            {"value": float("inf"), "winning": False, "chosen_index": -1,
             "chosen_input": (0.0, 0.0, 0.0)},
            "safe_input_indices",
            "recorded at value inf",
        ),  # outside the winning set, inputs are listed only to wait on one of them
    ],
)
def test_every_field_is_checked_against_the_others(
    changes: dict[str, object], field: str, text: str
) -> None:
    problems = consistency(_decision(**changes), INPUTS)
    assert any(f == field and text in t for f, t in problems), problems


def test_without_a_grid_the_chosen_input_is_checked_against_its_safe_row() -> None:
    ((field, text),) = consistency(_decision(chosen_input=(0.1, 0.0, 0.0)), None)
    assert field == "chosen_input"
    assert "the safe input of chosen_index 2 is [0.2, 0.0, 0.0]" in text


def test_inputs_of_equal_cost_tie(caches: ScenarioCache) -> None:
    scenario = load_scenario("coarse")
    controller = caches.get(scenario)(layout_from_scenario(scenario))
    grid = controller.inputs
    # J is even in the sway and yaw components when the previous input is zero.
    a = next(k for k, row in enumerate(grid) if row[1] > 0)
    mirrored = np.array([grid[a][0], -grid[a][1], grid[a][2]])
    b = int(np.flatnonzero(np.all(np.isclose(grid, mirrored), axis=1))[0])
    assert is_cost_tie(controller, a, b, np.zeros(3))
    c = next(k for k, row in enumerate(grid) if abs(row[0] - grid[a][0]) > 0.01)
    assert not is_cost_tie(controller, a, c, np.zeros(3))


def _across(locate: object, state: np.ndarray, beyond: float) -> np.ndarray:
    """Return `state` moved along x to `beyond` m past the nearest cell boundary above it."""
    cell = locate(state)  # type: ignore[operator]
    lo, hi = float(state[0]), float(state[0]) + 0.5
    assert locate(np.array([hi, state[1], state[2]])) != cell  # type: ignore[operator]
    for _ in range(80):  # bisect to the boundary, to the last bit
        mid = 0.5 * (lo + hi)
        if locate(np.array([mid, state[1], state[2]])) == cell:  # type: ignore[operator]
            lo = mid
        else:
            hi = mid
    return np.array([hi + beyond, state[1], state[2]])


@pytest.mark.parametrize(
    ("beyond", "accepted"), [(0.0, True), (BOUNDARY_TOLERANCE / 2, True), (1e-6, False)]
)
def test_a_decision_on_a_cell_boundary_is_accepted_either_way(
    caches: ScenarioCache, beyond: float, accepted: bool
) -> None:
    log = Path(__file__).resolve().parents[2] / "logs" / "coarse-high-seed2"
    run = load_run(log)
    controllers = caches.get(load_scenario("coarse"))
    k = next(i for i, d in enumerate(run.decisions) if d.winning and d.chosen_index >= 0)
    d = run.decisions[k]
    controller = controllers(layout_from_scenario(load_scenario("coarse")))
    moved = _across(controller.locate, np.array(d.state), beyond)
    assert controller.locate(moved) != d.cell  # the recorded state now lies in the next cell
    tampered = (*run.decisions[:k], dataclasses.replace(d, state=tuple(moved)),
                *run.decisions[k + 1:])
    tampered_run = dataclasses.replace(run, decisions=tampered)
    check = check_decisions(ReplayContext(tampered_run, load_scenario("coarse"), caches))
    if accepted:
        assert check.status is Status.PASS, check.findings
        assert check.metrics["boundary_decisions"] == 1
        assert "cell boundary" in check.summary
    else:
        assert check.status is Status.FAIL
        assert check.metrics["boundary_decisions"] == 0
        assert "cell" in check.findings[0].data["differ"]
