"""`[[simulated_motion]]` and `[sim]`: parsed into the scenario, every bad value named.

What the simulated obstacles do is checked against the obstacles it names and their
speed bounds (a motion faster than the synthesis budgets for is refused); the packaged
``paper-moving`` is the paper's problem with O2 tracked and moving back and forth.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hil.core.motion import ObstacleMotion, displacements_m
from hil.scenarios import ScenarioError, SimulatedWorld, load_scenario, parse_scenario

PAPER_TOML = Path(__file__).parents[2] / "hil" / "scenarios" / "paper.toml"


def _moving(*motions: dict[str, Any], sim: dict[str, Any] | None = None,
            o2_speed_mps: float = 0.05) -> dict[str, Any]:
    """The paper's data with O2's speed bound set and `motions` as [[simulated_motion]]."""
    data = tomllib.loads(PAPER_TOML.read_text(encoding="utf-8"))
    data["obstacles"][1]["max_speed_mps"] = o2_speed_mps
    data["simulated_motion"] = list(motions)
    if sim is not None:
        data["sim"] = sim
    return data


def _motion(**changes: Any) -> dict[str, Any]:
    return {"obstacle": "O2", "velocity_mps": [0.0, -0.05], "start_s": 5.0, "stop_s": 11.0,
            **changes}


def test_the_issue_example_parses_into_the_scenario() -> None:
    text = PAPER_TOML.read_text(encoding="utf-8").replace(
        'y_m = [0.0, 3.0]', 'y_m = [0.0, 3.0]\nmax_speed_mps = 0.05') + """
[sim]
obstacle_report_period_s = 0.5

[[simulated_motion]]     # what the simulated obstacle does; the stack sees only reports
obstacle = "O2"          # an [[obstacles]] name
velocity_mps = [0.0, -0.05]
start_s = 5.0
stop_s = 11.0
"""
    s = parse_scenario(tomllib.loads(text))
    assert s.simulation == SimulatedWorld((ObstacleMotion(1, (0.0, -0.05), 5.0, 11.0),), 0.5)
    assert s.simulation.moves_obstacles
    assert s.tracks_obstacles


def test_without_the_tables_nothing_moves_and_the_digest_is_unchanged() -> None:
    data = tomllib.loads(PAPER_TOML.read_text(encoding="utf-8"))
    s = parse_scenario(data)
    assert s.simulation == SimulatedWorld()
    assert s.simulation.obstacle_report_period_s == 1.0
    assert not s.simulation.moves_obstacles
    # Adding [[simulated_motion]] left this hash as it was; logs/paper-* carry it.
    assert s.digest() == "1639a60a26bc5d44"
    moving = parse_scenario(_moving(_motion()))
    assert moving.digest() != parse_scenario(_moving()).digest()  # the motion is hashed
    assert parse_scenario(_moving(sim={"obstacle_report_period_s": 2.0})).digest() != (
        parse_scenario(_moving()).digest())


def test_back_and_forth_entries_of_one_obstacle_follow_each_other() -> None:
    there = _motion(velocity_mps=[0.0, -0.05], start_s=5.0, stop_s=9.0)
    back = _motion(velocity_mps=[0.0, 0.05], start_s=9.0, stop_s=13.0)
    o1 = _motion(obstacle="O1", velocity_mps=[0.0, 0.02], start_s=6.0, stop_s=8.0)
    s = parse_scenario(_moving(there, back, o1,
                               sim={"obstacle_report_period_s": 1.0}) | {
        "obstacle_motion": {"max_speed_mps": 0.02}})
    assert [(m.index, m.start_s, m.stop_s) for m in s.simulation.motions] == [
        (1, 5.0, 9.0), (1, 9.0, 13.0), (0, 6.0, 8.0)]
    offsets = displacements_m(s.simulation.motions, 2, [0.0, 7.0, 9.0, 11.0, 13.0, 20.0])
    np.testing.assert_allclose(offsets[1, :, 1], [0.0, -0.1, -0.2, -0.1, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(offsets[0, :, 1], [0.0, 0.02, 0.04, 0.04, 0.04, 0.04], atol=1e-12)
    assert not offsets[:, :, 0].any()


@pytest.mark.parametrize(
    ("motions", "sim", "match"),
    [
        ([_motion(obstacle="O3")], None,
         r"key simulated_motion\[0\].'obstacle' = 'O3' names no \[\[obstacles\]\] entry "
         r"\(names: 'O1', 'O2'\)"),
        ([_motion(obstacle=2)], None, r"simulated_motion\[0\].'obstacle' = 2 names no"),
        ([{"velocity_mps": [0.0, 0.0], "stop_s": 1.0}], None,
         r"missing key simulated_motion\[0\].'obstacle'"),
        ([_motion(start_s=11.0, stop_s=5.0)], None,
         r"key simulated_motion\[0\].'stop_s' = 5.0 must be after simulated_motion\[0\]."
         r"'start_s' = 11.0"),
        ([_motion(stop_s=5.0)], None, r"'stop_s' = 5.0 must be after .*'start_s' = 5.0"),
        ([_motion(start_s=-1.0)], None, r"key simulated_motion\[0\].'start_s' must be >= 0"),
        ([_motion(stop_s=math.inf)], None,
         r"key simulated_motion\[0\].'stop_s' must be a finite number, got inf"),
        ([_motion(start_s=math.nan)], None, r"simulated_motion\[0\].'start_s' must be a finite"),
        ([_motion(velocity_mps=[math.nan, 0.0])], None,
         r"key simulated_motion\[0\].'velocity_mps' must be a list of 2 finite numbers"),
        ([_motion(velocity_mps=[0.05])], None, r"'velocity_mps' must be a list of 2 finite"),
        ([_motion(velocity_mps=[0.04, -0.04])], None,
         r"key simulated_motion\[0\].'velocity_mps' = \[0.04, -0.04\] moves 'O2' at "
         r"0.0565.* m/s, faster than its max_speed_mps = 0.05"),
        ([_motion(obstacle="O1", velocity_mps=[0.0, 0.01])], None,
         r"'velocity_mps' = \[0.0, 0.01\] moves 'O1' at 0.01 m/s, faster than its "
         r"max_speed_mps = 0.0"),
        ([_motion(), _motion(start_s=10.0, stop_s=12.0, velocity_mps=[0.0, 0.05])], None,
         r"key simulated_motion\[1\].'start_s' = 10.0, 'stop_s' = 12.0 overlaps "
         r"simulated_motion\[0\] of 'O2' \(\[5.0, 11.0\] s\)"),
        ([_motion(velocity_kn=[0.0, 0.1])], None,
         r"unknown key simulated_motion\[0\].'velocity_kn'"),
        ([3], None, r"key 'simulated_motion\[0\]' must be a table, got 3"),
        ([], {"obstacle_report_period_s": 0.0},
         r"key sim.'obstacle_report_period_s' must be > 0, got 0.0"),
        ([], {"obstacle_report_period_s": math.nan},
         r"key sim.'obstacle_report_period_s' must be a finite number"),
        ([], {"report_period_ms": 100}, r"unknown key sim.'report_period_ms'"),
    ],
)
def test_bad_simulated_motion_names_the_key_and_value(
    motions: list[Any], sim: dict[str, Any] | None, match: str
) -> None:
    with pytest.raises(ScenarioError, match=match):
        parse_scenario(_moving(*motions, sim=sim))


def test_simulated_motion_must_be_an_array_of_tables() -> None:
    data = _moving()
    data["simulated_motion"] = _motion()
    with pytest.raises(ScenarioError, match=r"key 'simulated_motion' must be an array of tables"):
        parse_scenario(data)


def test_an_obstacle_name_two_entries_share_is_refused() -> None:
    data = _moving(_motion())
    data["obstacles"][0]["name"] = "O2"
    data["obstacles"][0]["max_speed_mps"] = 0.05
    with pytest.raises(ScenarioError, match=r"'obstacle' = 'O2' is ambiguous: 2 \[\[obstacles"):
        parse_scenario(data)


def test_a_motion_at_the_bound_itself_passes() -> None:
    # 0.03, 0.04 -> 0.05 m/s up to rounding.
    s = parse_scenario(_moving(_motion(velocity_mps=[0.03, -0.04])))
    assert math.hypot(*s.simulation.motions[0].velocity_mps) == pytest.approx(0.05)


# ---------------------------------------------------------------- the packaged paper-moving


def test_paper_moving_is_the_paper_problem_with_o2_moving_back_and_forth() -> None:
    paper, moving = load_scenario("paper"), load_scenario("paper-moving")
    assert moving.name == "paper-moving"
    for key in ("x_range_m", "y_range_m", "cell_m", "heading_cells", "surge", "sway",
                "yaw_rate", "tau_s", "transient", "hull", "target", "tracking"):
        assert getattr(moving, key) == getattr(paper, key), key
    assert [o.shape for o in moving.obstacles] == [o.shape for o in paper.obstacles]
    assert [o.max_speed_mps for o in moving.obstacles] == [0.0, 0.05]
    assert moving.tracks_obstacles
    assert not paper.tracks_obstacles
    sim = moving.simulation
    assert sim.obstacle_report_period_s == 1.0
    assert {m.index for m in sim.motions} == {1}
    assert all(math.hypot(*m.velocity_mps) <= 0.05 for m in sim.motions)
    # Periodic: at the reports (every second) O2 takes only a few positions, bit for bit
    # the same each time round (a recurring layout is a recurring solve key).
    reports = np.arange(0.0, 200.0, sim.obstacle_report_period_s)
    dy = displacements_m(sim.motions, 2, reports)[1, :, 1]
    assert set(dy.tolist()) == {-k * 0.046875 for k in range(5)}
    assert dy[reports > 148.0].tolist() == [0.0] * int((reports > 148.0).sum())
    assert (dy[(reports >= 4.0) & (reports <= 148.0)] < 0.0).mean() > 0.7  # moving throughout
