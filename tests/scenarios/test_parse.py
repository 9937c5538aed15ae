"""Scenario parsing: validation errors naming the key, shapes told apart by their keys."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

import pytest

from hil.core.shapes import Polygon
from hil.scenarios import ScenarioError, parse_scenario

PAPER_TOML = Path(__file__).parents[2] / "hil" / "scenarios" / "paper.toml"


def _paper_data() -> dict[str, Any]:
    return tomllib.loads(PAPER_TOML.read_text(encoding="utf-8"))


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
        (["obstacles", "1", "x_m"], [-3.0, -2.5], r"'target' .* overlaps obstacles\[1\] \('O2'\)"),
        (["abstraction", "target_deflation_m"], 0.8, r"'target' is empty after deflation by 0.8"),
        (["target", "x_m"], [10.0, 11.0], r"'target' .* lies outside the state bounds"),
        (["obstacles"], {"x_m": 1}, r"'obstacles' must be an array of tables"),
        (["hull", "length_m"], -1.0, r"'hull' must have positive sizes"),
        (["margin"], {"none": True}, r"'margin' was retired: .*\[transient\].*bench lowlevel"),
        (["obstacle_motion", "max_speed_mps"], -0.1, r"motion.'max_speed_mps' must be >= 0"),
        (["obstacle_motion", "max_speed_mps"], math.nan, r"'max_speed_mps' must be a finite"),
        (["obstacle_motion", "max_speed_mps"], math.inf, r"'max_speed_mps' must be a finite"),
        (["obstacle_motion", "max_report_age_s"], 0.0, r"'max_report_age_s' must be > 0, got 0.0"),
        (["obstacle_motion", "max_report_age_s"], math.nan, r"'max_report_age_s' must be a finite"),
        (["obstacle_motion", "position_tolerance_m"], -0.01, r"'position_tolerance_m' must be >="),
        (["obstacle_motion", "position_tolerance_m"], math.nan, r"'position_tolerance_m' must"),
        (["obstacle_motion", "max_speed_kn"], 1.0, r"unknown key obstacle_motion.'max_speed_kn'"),
        (["obstacles", "1", "max_speed_mps"], -0.2, r"obstacles\[1\].'max_speed_mps' must be >= 0"),
        (["obstacles", "1", "max_speed_mps"], math.nan, r"\[1\].'max_speed_mps' must be a fin"),
        (["target", "max_speed_mps"], 0.1, r"unknown key target.'max_speed_mps'"),
        (["margin"], {"surge_mps": 0.01}, r"'margin' was retired"),
        (["obstacles", "0", "x_m"], [4.0, 5.0], r"obstacles\[0\] \('O1'\) .* outside the arena"),
        (["transient"], [1.0], r"key 'transient' must be a table"),
        (["transient", "bin_s"], KeyError, r"missing key transient.'bin_s'"),
        (["transient", "bin_s"], 0.3, r"transient.'bin_s' = 0.3 must be > 0 and divide"),
        (
            ["transient", "bin_s"],
            0.5,
            r"transient.'hold_position_m' must be a list of 5 finite.*0.5-s bin up to "
            r"timing.'tau_s' \+ 0.1 s",
        ),
        (["transient", "hold_sway_mps"], [0.01] * 8, r"'hold_sway_mps' must be a list of 9"),
        (["transient", "start_position_m"], [0.1] * 10, r"'start_position_m' must be a list of 9"),
        (["transient", "change_yaw_rate_radps"], [0.1] * 8 + [-0.1], r"'change_yaw_rate.* >= 0"),
        (["transient", "change_surge_mps"], KeyError, r"missing key transient.'change_surge_mps'"),
        (["transient", "start_heading_rad"], KeyError, r"missing key transient.'start_heading_"),
        (["transient", "hold_heading_rad"], [0.1] * 8 + [-0.1], r"'hold_heading_rad' must be >= 0"),
        (
            ["transient", "change_position_m"],
            [0.1, 0.2, 0.15] + [0.2] * 6,
            r"'change_position_m' must not decrease .* got 0.2 then 0.15 at bins 1-2",
        ),
        (["transient", "estimation_position_m"], -0.001, r"'estimation_position_m' must be >= 0"),
        (["transient", "estimation_heading_rad"], "1", r"'estimation_heading_rad' must be a fin"),
        (["transient", "source"], 3, r"transient.'source' must be a string"),
        (["transient", "hold_surge_deg"], [0.0] * 9, r"unknown key transient.'hold_surge_deg'"),
        (
            ["abstraction", "obstacle_inflation_m"],
            3.0,
            r"'target' cannot be reached: .* inflated obstacles",
        ),
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


def test_obstacle_speeds_default_to_the_table_and_obstacles_may_set_their_own() -> None:
    data = _paper_data()
    assert not parse_scenario(data).tracks_obstacles  # the tank's obstacles are fixed
    data["obstacle_motion"] = {"max_speed_mps": 0.05, "max_report_age_s": 0.5}
    data["obstacles"][1]["max_speed_mps"] = 0.2
    s = parse_scenario(data)
    assert [o.max_speed_mps for o in s.obstacles] == [0.05, 0.2]
    assert s.tracks_obstacles
    assert s.tracking.max_report_age_s == 0.5
    del data["obstacle_motion"]
    s = parse_scenario(data)
    assert [o.max_speed_mps for o in s.obstacles] == [0.0, 0.2]
    assert s.tracking.max_report_age_s == 1.0


def test_a_nan_speed_written_in_toml_is_refused() -> None:
    text = PAPER_TOML.read_text(encoding="utf-8").replace(
        "max_speed_mps = 0.0 ", "max_speed_mps = nan "
    )
    with pytest.raises(ScenarioError, match=r"obstacle_motion.'max_speed_mps' must be a finite"):
        parse_scenario(tomllib.loads(text))


def test_transient_table_reads_into_the_budget() -> None:
    data = _paper_data()
    s = parse_scenario(data)
    raw = data["transient"]
    b = s.transient
    assert b.n_bins == 9
    assert b.n_classes == 3
    assert b.horizon_s() == pytest.approx(s.tau_s + 0.25)  # covers tau + 0.1 s
    assert b.position_m[0].tolist() == raw["hold_position_m"]
    assert b.position_m[2].tolist() == raw["start_position_m"]
    assert b.heading_rad[1].tolist() == raw["change_heading_rad"]
    assert b.envelopes[0, :, 0].tolist() == raw["hold_surge_mps"]
    assert b.envelopes[0, :, 2].tolist() == raw["hold_yaw_rate_radps"]
    assert b.envelopes[1, :, 1].tolist() == raw["change_sway_mps"]
    assert b.envelopes[2, :, 2].tolist() == raw["start_yaw_rate_radps"]
    assert b.estimation_position_m == raw["estimation_position_m"]
    assert b.source == raw["source"]


def test_missing_transient_table_is_the_zero_budget() -> None:
    s = parse_scenario(_edit(["transient"], KeyError))
    assert s.transient.is_zero()
    assert s.transient.n_bins == 9
    assert s.transient.horizon_s() >= s.tau_s + 0.1
    assert s.digest() != parse_scenario(_paper_data()).digest()  # the digest covers it
    for key in ("hold_surge_mps", "start_position_m", "change_heading_rad"):
        zeroed = _edit(["transient", key], [0.0] * 9)
        assert parse_scenario(zeroed).digest() != parse_scenario(_paper_data()).digest()
