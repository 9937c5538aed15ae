"""The scenario margin is what the shipped low level achieves, re-derived from its code."""

from __future__ import annotations

import numpy as np
import pytest

from hil.scenarios import load_scenario, packaged_scenarios
from hil.sim.margin import (
    MARGIN_DIGITS,
    MarginRecipe,
    derive_margin,
    input_grid,
    margin_from,
    random_walk_refs,
)

QUANTUM = 10.0**-MARGIN_DIGITS
# Numba compiles for the host CPU, so the closed loop differs between machines by ~1e-10;
# the derived maximum is compared with the shipped (rounded-up) entry to well above that.
MACHINE_NOISE = 1e-8


def test_random_walk_stays_on_the_grid_one_step_at_a_time() -> None:
    grid = input_grid(load_scenario("paper"))
    lo, hi, step = grid
    refs = random_walk_refs(400, 3, grid)
    assert np.all(refs >= lo - 1e-12)
    assert np.all(refs <= hi + 1e-12)
    np.testing.assert_allclose((refs - lo) / step, np.round((refs - lo) / step), atol=1e-9)
    jumps = np.abs(np.diff(np.vstack([np.zeros((1, 3)), refs]), axis=0)) / step
    assert jumps.max() <= 1.0 + 1e-9
    assert len({tuple(r) for r in refs}) > 20  # it does walk


def test_margin_rounds_up_to_the_quantum() -> None:
    out = margin_from(np.array([0.02721, 0.0259, 0.05281]))
    np.testing.assert_allclose(out, [0.0273, 0.0259, 0.0529])


@pytest.mark.parametrize("name", sorted(packaged_scenarios()))
def test_packaged_scenarios_ship_the_margin_the_low_level_achieves(name: str) -> None:
    scenario = load_scenario(name)
    shipped = scenario.margin.as_array()
    measured = derive_margin(scenario, MarginRecipe())
    # Shipped = the measured maximum rounded up: re-run `python3 tools/dev.py bench lowlevel`
    # and copy its [margin] table when gains, thrusters or the vessel change.
    assert np.all(measured.worst <= shipped + MACHINE_NOISE), (measured.worst, shipped)
    assert np.all(measured.worst > shipped - QUANTUM - MACHINE_NOISE), (measured.worst, shipped)
    assert np.all(measured.p99 < measured.worst)
    assert "hil.sim.margin" in scenario.margin.source
