"""Scenario files: the packaged arena, validation errors naming the key, geometry helpers."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hil.scenarios.scenario import (
    Polygon,
    Rect,
    ScenarioError,
    convex_distance_m,
    load_scenario,
    packaged_scenarios,
    parse_scenario,
)

PAPER_TOML = Path(__file__).parents[2] / "hil" / "scenarios" / "paper.toml"


def _paper_data() -> dict[str, Any]:
    return tomllib.loads(PAPER_TOML.read_text(encoding="utf-8"))


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
    assert s.margin.as_array().tolist() == [0.0106, 0.0216, 0.0382]  # the low level's bound


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


def _edit(path: list[str], value: Any) -> dict[str, Any]:
    data = _paper_data()
    node: Any = data
    for key in path[:-1]:
        node = node[key] if not key.isdigit() else node[int(key)]
    if value is KeyError:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return data


@pytest.mark.parametrize(
    ("path", "value", "match"),
    [
        (["state"], KeyError, "missing key 'state'"),
        (["state", "x_m"], [1.0, 1.0], r"state.'x_m' is empty"),
        (["state", "y_m"], [0.0, "3"], r"state.'y_m' must be a list of 2 finite numbers"),
        (["grid", "cell_m"], [0.03, 0.05], r"grid.'cell_m' x width 0.03 does not divide"),
        (["grid", "heading_cells"], 0, r"grid.'heading_cells' must be a positive integer"),
        (["grid", "heading_cells"], KeyError, r"missing key grid.'heading_cell_rad'"),
        (["grid", "heading_cell_deg"], 6.0, r"unknown key grid.'heading_cell_deg'"),
        (["inputs", "surge_mps"], [-0.1, 0.2, 0.07], r"inputs.'surge_mps'.*step > 0 dividing"),
        (
            ["inputs", "yaw_rate_radps"],
            [-20.0, 20.0, 10.0],
            r"inputs.'yaw_rate_radps'.*degrees given",
        ),
        (["timing", "tau_s"], 2000.0, r"timing.'tau_s' = 2000.0 .*milliseconds given"),
        (["timing", "tau_ms"], 2000, r"unknown key timing.'tau_ms'"),
        (["margin", "surge_mps"], -0.01, r"margin.'surge_mps' must be >= 0"),
        (["obstacles", "1", "x_m"], [-3.0, -2.5], r"'target' .* overlaps obstacles\[1\] \('O2'\)"),
        (["abstraction", "target_deflation_m"], 0.8, r"'target' is empty after deflation by 0.8"),
        (["target", "x_m"], [10.0, 11.0], r"'target' .* lies outside the state bounds"),
        (["obstacles"], {"x_m": 1}, r"'obstacles' must be an array of tables"),
        (["hull", "length_m"], -1.0, r"'hull' must have positive sizes"),
    ],
)
def test_bad_scenarios_name_the_key(path: list[str], value: Any, match: str) -> None:
    with pytest.raises(ScenarioError, match=match):
        parse_scenario(_edit(path, value))


def test_heading_cell_width_must_divide_the_circle() -> None:
    data = _edit(["grid", "heading_cells"], KeyError)
    data["grid"]["heading_cell_rad"] = 0.1
    with pytest.raises(ScenarioError, match=r"grid.'heading_cell_rad' = 0.1 does not divide 2 pi"):
        parse_scenario(data)
    data["grid"]["heading_cell_rad"] = 2 * math.pi / 36
    assert parse_scenario(data).heading_cells == 36


def test_rotated_and_polygon_obstacles_parse() -> None:
    data = _paper_data()
    data["obstacles"] = [
        {"name": "boat", "center_m": [1.0, 1.0], "size_m": [1.0, 0.4], "angle_rad": 0.5},
        {"name": "tri", "vertices_m": [[3.0, -2.0], [4.0, -2.0], [3.5, -1.0]], "inflation_m": 0.1},
    ]
    s = parse_scenario(data)
    assert isinstance(s.obstacles[0].shape, Polygon)
    inflated = s.obstacles[1].inflated
    assert isinstance(inflated, Polygon)
    # Each edge moved out by 0.1 m: the bottom edge y = -2 becomes y = -2.1.
    assert min(p[1] for p in inflated.vertices_m) == pytest.approx(-2.1)
    data["obstacles"] = [{"vertices_m": [[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]]}]  # clockwise
    with pytest.raises(
        ScenarioError, match=r"obstacles\[0\].'vertices_m' is not a convex counter-clockwise"
    ):
        parse_scenario(data)


def test_hull_clearance_closed_form() -> None:
    s = load_scenario("paper")
    # Hull 0.99 x 0.31 at (1, 1) heading 0: corner (1.495, 0.845) to O1's corner (1.75, 0).
    assert s.hull_clearance_m(1.0, 1.0, 0.0) == pytest.approx(math.hypot(0.255, 0.845))
    # Turned 90 deg: corner (1.155, 0.505).
    assert s.hull_clearance_m(1.0, 1.0, math.pi / 2) == pytest.approx(math.hypot(0.595, 0.505))
    assert s.hull_clearance_m(2.0, -1.0, 0.3) == 0.0  # inside O1
    assert s.wall_clearance_m(0.0, 0.0, 0.0) == pytest.approx(3.0 - 0.155)
    assert convex_distance_m(Rect(0, 1, 0, 1), Rect(2, 3, 0, 1)) == pytest.approx(1.0)


def test_moved_layout_keeps_the_rest() -> None:
    s = load_scenario("coarse")
    moved = s.with_obstacles_moved(np.array([[0.5, 0.0], [0.0, -0.25]]))
    assert moved.obstacles[0].shape == Rect(2.25, 2.75, -3.0, 0.0)
    assert moved.obstacles[1].shape == Rect(-1.25, -0.75, -0.25, 2.75)
    assert moved.target == s.target
    assert moved.cell_m == s.cell_m
    with pytest.raises(ScenarioError, match="overlaps"):
        s.with_obstacles_moved(np.array([[0.0, 0.0], [-1.5, 0.0]]))


def test_digest_follows_the_content() -> None:
    s = load_scenario("coarse")
    assert s.digest() == load_scenario("coarse").digest()
    assert s.digest() != s.with_obstacles_moved(np.array([[0.1, 0.0], [0.0, 0.0]])).digest()
