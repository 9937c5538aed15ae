"""The decisions check: a recorded decision taken again with the current code."""

from __future__ import annotations

import numpy as np

from hil.replay.controllers import ScenarioCache
from hil.replay.decisions import recompute
from hil.runtime.assembly import layout_from_scenario
from hil.scenarios import load_scenario


def test_recompute_mirrors_the_runtime_decision(caches: ScenarioCache) -> None:
    scenario = load_scenario("coarse")
    controller = caches.get(scenario)(layout_from_scenario(scenario))
    start = np.array([3.75, -1.5, np.pi / 2])
    got = recompute(controller, start, np.zeros(3))
    assert got.winning
    assert got.value > 0
    assert got.chosen in got.safe
    assert len(got.safe) >= 1
    in_target = recompute(controller, np.array([-2.75, 1.5, 0.0]), np.zeros(3))
    assert (in_target.value, in_target.safe, in_target.chosen) == (0.0, (), -1)
    outside = recompute(controller, np.array([2.0, -1.5, 0.0]), np.zeros(3))  # inside O1
    assert not outside.winning
    assert outside.chosen == -1
