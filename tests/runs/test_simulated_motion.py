"""A scenario's `[[simulated_motion]]` in the simulated world, its summary and its truth judge.

The world moves the obstacles the scenario schedules (with a spec's own motions added)
and reports them every ``[sim] obstacle_report_period_s``; the run summary's clearance
and the campaign's guarantee judge place each obstacle where it truly is at each step,
so a hull the moving obstacle runs into is a contact, which the layout of t = 0 would
miss. Specs keep only their own motions: ``logs/suite.json`` reads back unchanged.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from hil.adapters.sim import SimWorld
from hil.core.motion import ObstacleMotion
from hil.core.shapes import Rect
from hil.runs.clearance import hull_clearance_series
from hil.runs.guarantee import judge_outcome, judge_run, judged_run
from hil.runs.sim_run import (
    SimOutcome,
    SimRunSpec,
    sim_config,
    spec_from_json,
    spec_to_json,
    summarize,
    world_motions,
)
from hil.runtime.settings import LoopConfig
from hil.runtime.stats import RunStats
from hil.scenarios import Scenario, load_scenario
from hil.sim.plant import TR_ETA

ROOT = Path(__file__).parents[2]
COARSE = ROOT / "hil" / "scenarios" / "coarse.toml"
NS_PER_S = 1_000_000_000


def _coarse_moving(folder: Path, motions: str, period_s: float = 1.0,
                   o2_speed_mps: float = 0.1, o2_bottom_m: float = 0.0) -> Path:
    """The coarse scenario with O2 (obstacle 0) tracked at `o2_speed_mps` and `motions`.

    ``o2_bottom_m`` moves O2's lower edge (from y = 0): a shorter O2 leaves the passage
    below it wide enough for the growth of a tracked obstacle.
    """
    text = COARSE.read_text(encoding="utf-8")
    assert 'y_m = [0.0, 3.0]\n' in text
    path = folder / "coarse-moving.toml"
    path.write_text(
        text.replace('y_m = [0.0, 3.0]\n',
                     f'y_m = [{o2_bottom_m}, 3.0]\nmax_speed_mps = {o2_speed_mps}\n')
        + f"\n[sim]\nobstacle_report_period_s = {period_s}\n" + motions, encoding="utf-8")
    return path


def _entry(velocity: tuple[float, float], start_s: float, stop_s: float) -> str:
    return (f'\n[[simulated_motion]]\nobstacle = "O2"\nvelocity_mps = {list(velocity)}\n'
            f"start_s = {start_s}\nstop_s = {stop_s}\n")


# ---------------------------------------------------------------- the world


def test_the_world_moves_the_scenarios_obstacle_as_scheduled(tmp_path: Path) -> None:
    # Down 0.1 m/s over 1-3 s, back up over 3-5 s, reported every 0.5 s; the spec adds
    # a push right at 0.05 m/s over 2-4 s (fault injection, as record-suite schedules).
    path = _coarse_moving(tmp_path, _entry((0.0, -0.1), 1.0, 3.0) + _entry((0.0, 0.1), 3.0, 5.0),
                          period_s=0.5)
    scenario = load_scenario(path)
    push = ObstacleMotion(0, (0.05, 0.0), 2.0, 4.0)
    spec = SimRunSpec(scenario=str(path), motions=(push,))
    assert world_motions(scenario, spec) == (*scenario.simulation.motions, push)
    world = SimWorld(sim_config(spec, scenario), max_duration_s=10.0)
    assert world.config.obstacle_report_period_s == 0.5
    o2 = Rect(-1.25, -0.75, 0.0, 3.0)
    assert world.obstacles.latest().obstacles == (o2,)
    want = {  # report time (s) -> O2's displacement (m)
        0.5: (0.0, 0.0), 1.5: (0.0, -0.05), 2.0: (0.0, -0.1), 3.0: (0.05, -0.2),
        3.5: (0.075, -0.15), 4.5: (0.1, -0.05), 5.0: (0.1, 0.0), 8.0: (0.1, 0.0)}
    for t_s, (dx, dy) in want.items():
        world.clock.sleep_until(round(t_s * NS_PER_S))
        layout = world.obstacles.latest()
        assert layout.t_ns == round(t_s * NS_PER_S)
        (got,) = layout.obstacles
        np.testing.assert_allclose(
            [got.x_min_m, got.x_max_m, got.y_min_m, got.y_max_m],
            [o2.x_min_m + dx, o2.x_max_m + dx, o2.y_min_m + dy, o2.y_max_m + dy], atol=1e-12,
            err_msg=f"t = {t_s} s")
    # Between reports the tracker's last report stands.
    world.clock.sleep_until(round(8.4 * NS_PER_S))
    assert world.obstacles.latest().t_ns == 8 * NS_PER_S


def test_a_scenario_without_motions_keeps_the_layout_of_t0(tmp_path: Path) -> None:
    scenario = load_scenario("coarse")
    world = SimWorld(sim_config(SimRunSpec(scenario="coarse"), scenario), max_duration_s=5.0)
    assert world.config.motions == ()
    first = world.obstacles.latest()
    world.clock.sleep_until(3 * NS_PER_S)
    assert world.obstacles.latest() is first


# ---------------------------------------------------------------- summary and truth judge


def _parked(tmp_path: Path) -> tuple[SimRunSpec, SimOutcome]:
    """A vessel parked at the origin, bow along +x, as O2 slides onto it (0.1 m/s, 0-10 s)."""
    path = _coarse_moving(tmp_path, _entry((0.1, 0.0), 0.0, 10.0))
    scenario = load_scenario(path)
    spec = SimRunSpec(scenario=str(path), start=(0.0, 0.0, 0.0),
                      loop=LoopConfig(max_duration_s=10.0))
    world = SimWorld(sim_config(spec, scenario), max_duration_s=12.0)
    world.clock.sleep_until(10 * NS_PER_S)  # no thrust: the hull stays where it is
    stats = RunStats(end_ns=10 * NS_PER_S)
    return spec, SimOutcome(summarize(spec, scenario, world, stats, 0.0), scenario, world,
                            stats, {})


def test_the_truth_judge_sees_the_moving_obstacle_hit_the_hull(tmp_path: Path) -> None:
    spec, outcome = _parked(tmp_path)
    truth = outcome.sim.truth()
    t_s, eta = truth[:, 0], truth[:, 1 + TR_ETA : 1 + TR_ETA + 3]
    np.testing.assert_allclose(eta, 0.0, atol=1e-12)  # parked
    judged = judge_outcome(spec, outcome, [])
    # After 10 s O2 spans x [-0.25, 0.25]: through the hull (x [-0.495, 0.495], beam 0.31,
    # O2 from y = 0 up): 0.155 m deep, and the centre 0.5 m into the inflated O2.
    assert judged.hull_contacts == 1
    assert judged.worst_hull_penetration_m == pytest.approx(0.155, abs=0.002)
    assert judged.inflated_obstacle == 1
    # Against the layout of t = 0 (O2 0.255 m left of the hull) the same truth is clean.
    assert judge_run(outcome.scenario, [], {}, t_s, eta).violations == 0
    # The summary's clearance places O2 where it is too.
    summary = outcome.summary
    assert summary.moving_obstacles == 1
    assert summary.min_clearance_m == 0.0
    assert summary.hull_contacts > 0
    still = hull_clearance_series(outcome.scenario, eta)
    assert still.min() == pytest.approx(1.25 - 0.5 - 0.495)


# ---------------------------------------------------------------- specs


def test_specs_keep_their_own_motions_and_the_suite_reads_back_unchanged() -> None:
    manifest = json.loads((ROOT / "logs" / "suite.json").read_text(encoding="utf-8"))
    assert manifest["runs"]
    for name, entry in manifest["runs"].items():
        spec = spec_from_json(entry)
        assert {**spec_to_json(spec), "note": entry["note"]} == entry, name
    moving = next(e for e in manifest["runs"].values() if e["motions"])
    assert spec_from_json(moving).motions == (ObstacleMotion(0, (0.0, 0.05), 4.0, 8.0),)
    # A spec of a moving scenario writes only its own motions; the scenario adds its own.
    spec = SimRunSpec(scenario="paper-moving", seed=2,
                      motions=(ObstacleMotion(0, (0.01, 0.0), 1.0, 2.0),))
    data = spec_to_json(spec)
    assert data["motions"] == [{"index": 0, "velocity_mps": [0.01, 0.0], "start_s": 1.0,
                                "stop_s": 2.0}]
    assert spec_from_json(json.loads(json.dumps(data))) == spec
    scenario = load_scenario("paper-moving")
    assert world_motions(scenario, spec) == (*scenario.simulation.motions, *spec.motions)


# ---------------------------------------------------------------- closed loop


@pytest.fixture(scope="module")
def coarse_moving(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("coarse-moving")
    # O2 down 0.1 m and back, twice, at 0.05 m/s (4 positions, each solved once).
    motions = "".join(_entry((0.0, -0.05), 4.0 + 4.0 * k, 6.0 + 4.0 * k)
                      + _entry((0.0, 0.05), 6.0 + 4.0 * k, 8.0 + 4.0 * k) for k in range(2))
    return _coarse_moving(folder, motions, o2_speed_mps=0.05, o2_bottom_m=0.5)


@pytest.mark.slow  # one coarse run with 3 new layouts: ~30 s on 2 busy cores
def test_a_judged_run_of_a_moving_scenario_moves_and_resynthesizes(
    coarse_moving: Path, tmp_path: Path
) -> None:
    scenario: Scenario = load_scenario(coarse_moving)
    spec = SimRunSpec(scenario=str(coarse_moving), seed=3, cache_dir=tmp_path / "tables",
                      loop=LoopConfig(max_duration_s=90.0))
    summary, judged = judged_run(spec)
    assert summary.moving_obstacles == 1
    assert summary.resyntheses >= 8  # a new layout at every report while O2 moves
    assert summary.obstacle_stale_stops == 0
    assert summary.docked
    assert judged.violations == 0
    assert judged.intervals >= 10
    assert math.isfinite(summary.min_clearance_m)
    assert summary.min_clearance_m > 0.0
    assert scenario.simulation.moves_obstacles
