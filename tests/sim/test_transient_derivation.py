"""The scenario's transient budget is what the shipped low level achieves, and it bounds the arc."""

from __future__ import annotations

import functools
import itertools
import tomllib
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

import hil.scenarios
from hil.core.transient import BudgetClass
from hil.scenarios import Scenario, load_scenario, packaged_scenarios, parse_scenario
from hil.sim.transient import (
    DIGITS,
    Run,
    TransientDerivation,
    TransientRecipe,
    check_bound,
    classify,
    derive_transient,
    euler_tour,
    recipe_runs,
    round_up,
    toml_table,
)

QUANTUM = 10.0**-DIGITS
# Numba compiles for the host CPU, so the closed loop differs between machines by ~1e-10:
# a derived entry may round to the next step. Shipped and derived are compared to one
# rounding step either way, never bit for bit.
STEP = QUANTUM + 1e-9


def _grid_key(scenario: Scenario) -> tuple[object, ...]:
    return (scenario.surge, scenario.sway, scenario.yaw_rate, scenario.tau_s)


@functools.cache
def _derived(key: tuple[object, ...]) -> TransientDerivation:
    # The derivation sees only the input grid and the period: scenarios sharing them
    # share one (the default recipe takes ~15 s on one core).
    name = next(n for n in sorted(packaged_scenarios()) if _grid_key(load_scenario(n)) == key)
    return derive_transient(load_scenario(name), TransientRecipe())


def _index(scenario: Scenario, refs: NDArray[np.float64]) -> NDArray[np.int64]:
    lo = np.array([scenario.surge.min, scenario.sway.min, scenario.yaw_rate.min])
    step = np.array([scenario.surge.step, scenario.sway.step, scenario.yaw_rate.step])
    idx = (refs - lo) / step
    np.testing.assert_allclose(idx, np.round(idx), atol=1e-9)  # on the grid
    out: NDArray[np.int64] = np.round(idx).astype(np.int64)
    return out


def test_an_euler_tour_flies_every_pair_once() -> None:
    scenario = load_scenario("paper")
    refs = euler_tour(scenario, np.random.default_rng(1), hold_p=0.0)
    idx = _index(scenario, np.vstack([np.zeros((1, 3)), refs]))  # from rest at 0
    steps = np.diff(idx, axis=0)
    assert np.abs(steps).max() == 1
    pairs = Counter((tuple(a), tuple(b)) for a, b in itertools.pairwise(idx))
    # 7 x 5 x 5 inputs; per axis sum over p of |N(p)| = 3n - 2, so 19 * 13 * 13 pairs.
    assert len(pairs) == 19 * 13 * 13
    assert set(pairs.values()) == {1}
    assert np.all(idx[-1] == idx[0])


def test_tours_hold_after_changes_and_stay_on_the_grid() -> None:
    scenario = load_scenario("paper")
    refs = euler_tour(scenario, np.random.default_rng(2))
    idx = _index(scenario, np.vstack([np.zeros((1, 3)), refs]))
    assert np.abs(np.diff(idx, axis=0)).max() == 1
    holds = np.all(np.diff(idx, axis=0) == 0, axis=1)
    assert 0.2 < holds.mean() < 0.35  # 1 in 27 from the tour, 1/3 after its changes


def test_recipe_runs_obey_the_rule() -> None:
    scenario = load_scenario("paper")
    recipe = TransientRecipe(tours=1, walks=2, walk_s=40.0)
    runs = recipe_runs(scenario, recipe)
    kinds = Counter(r.kind for r in runs)
    assert kinds == {"tour": 1, "walk": 2, "sweeps": 1, "moving": 3211, "corner": 3211}
    half = 0.5 * np.array([0.05, 0.05, 0.1]) + 1e-12
    for run in runs:
        idx = _index(scenario, np.vstack([run.previous[None, :], run.refs]))
        assert np.abs(np.diff(idx, axis=0)).max() <= 1
        if run.moving:
            assert np.all(np.abs(run.nu0 - run.previous) <= half)
            assert classify(run)[0] == BudgetClass.CHANGE
        else:
            assert np.all(run.nu0 == 0.0)
    again = recipe_runs(scenario, recipe)  # deterministic in the seed
    assert all(
        np.array_equal(a.refs, b.refs) and np.array_equal(a.nu0, b.nu0)
        for a, b in zip(runs, again, strict=True)
    )
    other = recipe_runs(scenario, TransientRecipe(tours=1, walks=2, walk_s=40.0, seed=1))
    assert not np.array_equal(runs[0].refs[:50], other[0].refs[:50])


def test_periods_are_classified_by_the_previous_reference() -> None:
    refs = np.array([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.05, 0.0, 0.0], [0.05, -0.05, 0.1]])
    z = np.zeros(3)
    rest = Run("walk", refs, z, z, z, 0, moving=False)
    assert classify(rest).tolist() == [0, 1, 0, 1]
    moving = Run("moving", refs, z, np.array([0.01, 0.0, 0.0]), z, 0, moving=True)
    assert classify(moving).tolist() == [1, 1, 0, 1]


def test_round_up_to_the_quantum() -> None:
    np.testing.assert_allclose(round_up(np.array([0.02721, 0.0259, 0.0])), [0.0273, 0.0259, 0.0])


def test_the_toml_table_reads_back() -> None:
    scenario = load_scenario("paper")
    text = (Path(hil.scenarios.__file__).parent / "paper.toml").read_text(encoding="utf-8")
    data = tomllib.loads(text)
    data["transient"] = tomllib.loads(toml_table(scenario.transient))["transient"]
    assert parse_scenario(data).transient == scenario.transient


@pytest.mark.parametrize("name", sorted(packaged_scenarios()))
def test_packaged_scenarios_ship_the_budget_the_low_level_achieves(name: str) -> None:
    scenario = load_scenario(name)
    shipped = scenario.transient
    derived = _derived(_grid_key(scenario))
    # Shipped = the derived budget: re-run `python3 tools/dev.py bench lowlevel` and copy
    # its [transient] table when gains, thrusters, the observer or the vessel change.
    want = derived.budget
    assert shipped.bin_s == pytest.approx(want.bin_s)
    assert shipped.envelopes.shape == want.envelopes.shape
    assert np.all(shipped.envelopes >= want.envelopes - STEP), (shipped, want)
    assert np.all(shipped.envelopes <= want.envelopes + STEP), (shipped, want)
    for key in ("estimation_position_m", "estimation_heading_rad"):
        assert getattr(want, key) - STEP <= getattr(shipped, key) <= getattr(want, key) + STEP
    assert "hil.sim.transient" in shipped.source
    # The runs the budget comes from stay inside the bound it implies.
    assert derived.ratios.worst < 1.0
    assert np.all(derived.periods > 1000)


def test_fresh_runs_stay_inside_the_shipped_bound() -> None:
    scenario = load_scenario("paper")
    # Other seeds than the derivation's: new tours, walks and moving starts.
    recipe = TransientRecipe(tours=1, walks=0, sweeps=False, moving_share=0.15, seed=9100)
    ratios = check_bound(scenario, scenario.transient, recipe)
    assert np.all(ratios.periods > 500)
    assert ratios.worst < 1.0, ratios
    assert ratios.position.min() > 0.1  # not vacuous
