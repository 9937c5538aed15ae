"""Scenario catalog: packaged scenarios by name, any TOML file by path."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hil.core.shapes import Rect
from hil.scenarios import ScenarioError, load_scenario, packaged_scenarios

PAPER_TOML = Path(__file__).parents[2] / "hil" / "scenarios" / "paper.toml"


def test_paper_scenario_reproduces_the_arena() -> None:
    s = load_scenario("paper")
    assert s.x_range_m == (-3.5, 4.5)
    assert s.y_range_m == (-3.0, 3.0)
    assert s.cell_m == (0.05, 0.05)
    assert s.heading_cells == 60
    assert s.inputs().shape == (175, 3)
    np.testing.assert_allclose(
        s.surge.values(), [-0.1, -0.05, 0.0, 0.05, 0.1, 0.15, 0.2], atol=1e-12
    )
    assert s.tau_s == 2.0
    assert s.inflated_obstacles() == (Rect(1.25, 2.75, -3.5, 0.5), Rect(-1.75, -0.25, -0.5, 3.5))
    assert s.abstract_target() == Rect(-3.25, -2.25, 1.0, 2.0)
    assert [o.shape for o in s.obstacles] == [
        Rect(1.75, 2.25, -3.0, 0.0),
        Rect(-1.25, -0.75, 0.0, 3.0),
    ]
    assert (s.hull.length_m, s.hull.beam_m) == (0.99, 0.31)


def test_packaged_names_and_paths_both_load(tmp_path: Path) -> None:
    assert {"paper", "coarse"} <= set(packaged_scenarios())
    copy = tmp_path / "mine.toml"
    copy.write_text(PAPER_TOML.read_text(encoding="utf-8"), encoding="utf-8")
    assert load_scenario(copy) == load_scenario("paper")
    assert load_scenario(str(copy)).name == "paper"
    with pytest.raises(ScenarioError, match="no scenario named 'nope'"):
        load_scenario("nope")
    with pytest.raises(ScenarioError, match="cannot read"):
        load_scenario(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = [", encoding="utf-8")
    with pytest.raises(ScenarioError, match="not valid TOML"):
        load_scenario(bad)
