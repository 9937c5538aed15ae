"""The guarantee judged on the true state: closed forms, a coarse run, the audit's counterexample.

Safety sizes are checked against hand-computed geometry (a hull parked while an
obstacle slides onto it), interval bookkeeping against decisions removed by hand,
the estimation count against Grid.cell_of on the true poses, and the judge's
tube and inflated-obstacle flags against GUARANTEE.md's closed-loop counterexample
re-flown with the real low level in the simulated world.
"""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

import hil.scenarios
from hil.adapters.sim import ObstacleMotion
from hil.controllers.symbolic import DecisionContract
from hil.runs.guarantee import GuaranteeViolations, judge_outcome, judge_run
from hil.runs.sim_run import SimOutcome, SimRunSpec, simulate, spec_from_json, spec_to_json
from hil.runtime.assembly import select_index
from hil.runtime.settings import LoopConfig
from hil.runtime.trace import MemoryLog
from hil.scenarios import load_scenario
from hil.sim.plant import TR_ETA, TR_NU

FloatArray = NDArray[np.float64]

LOOP = LoopConfig(resynthesis_period_s=None, max_duration_s=240.0)


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("tables")


@pytest.fixture(scope="module")
def coarse_run(cache_dir: Path) -> tuple[SimRunSpec, SimOutcome, MemoryLog]:
    spec = SimRunSpec(scenario="coarse", seed=1, loop=LOOP, cache_dir=cache_dir,
                      start_velocity=(0.1, -0.05, 0.1))
    log = MemoryLog()
    return spec, simulate(spec, log=log), log


def _cell(outcome: SimOutcome, flat: int) -> tuple[int, int, int]:
    i, j, k = np.unravel_index(flat, outcome.controllers[1].grid.shape)
    return int(i), int(j), int(k)


def _eta(outcome: SimOutcome) -> tuple[FloatArray, FloatArray]:
    truth = outcome.sim.truth()
    return truth[:, 0], truth[:, 1 + TR_ETA : 1 + TR_ETA + 3]


# ---------------------------------------------------------------- safety, closed forms


def test_an_obstacle_sliding_onto_a_parked_hull_is_measured() -> None:
    scenario = load_scenario("coarse")  # O2 = [-1.25, -0.75] x [0, 3], inflated by 0.5
    t = np.arange(0.0, 10.0, 0.01)
    eta = np.zeros((len(t), 3))  # parked at the origin, bow along +x: hull [-0.495, 0.495]
    # O2 slides right at 0.1 m/s: after 10 s it spans x [-0.25, 0.25], y [0, 3].
    motion = ObstacleMotion(0, (0.1, 0.0), 0.0, 10.0)
    judged = judge_run(scenario, [], {}, t, eta, motions=[motion])
    assert judged.hull_contacts == 1
    assert judged.inflated_obstacle == 1
    # Hull beam is 0.31: the obstacle overlaps it by 0.155 in y, 0.5 in x.
    assert judged.worst_hull_penetration_m == pytest.approx(0.155, abs=0.002)
    # The inflated O2 ends at [-0.75, 0.75] x [-0.5, 3.5]: the origin is 0.5 deep.
    assert judged.worst_inflated_depth_m == pytest.approx(0.5 - 0.001, abs=0.002)
    assert judged.hull_outside_arena == 0
    # Without the motion nothing touches.
    still = judge_run(scenario, [], {}, t, eta)
    assert still.violations == 0


def test_a_hull_over_the_wall_is_measured() -> None:
    scenario = load_scenario("coarse")  # x in [-3.5, 4.5]
    t = np.arange(0.0, 1.0, 0.01)
    eta = np.tile([4.3, 0.0, 0.0], (len(t), 1))
    judged = judge_run(scenario, [], {}, t, eta)
    assert judged.hull_outside_arena == 1
    assert judged.worst_hull_outside_m == pytest.approx(4.3 + 0.495 - 4.5)
    turned = judge_run(scenario, [], {}, t, np.tile([4.3, 0.0, math.pi / 2], (len(t), 1)))
    assert turned.hull_outside_arena == 0  # the beam, not the length, faces the wall


# ---------------------------------------------------------------- a coarse run


def test_a_coarse_run_keeps_its_bookkeeping(
    coarse_run: tuple[SimRunSpec, SimOutcome, MemoryLog]
) -> None:
    spec, outcome, log = coarse_run
    judged = judge_outcome(spec, outcome, log.decisions)
    assert outcome.summary.docked
    assert judged.decisions == len(log.decisions)
    assert judged.intervals == sum(d.chosen_index >= 0 for d in log.decisions)
    assert judged.late_intervals == 0
    # The estimate: the decision's cell against Grid.cell_of at the true pose.
    _, eta = _eta(outcome)
    controller = outcome.controllers[1]
    grid = controller.grid
    misses = 0
    for d in log.decisions:
        cell = grid.cell_of(eta[round(d.t_ns / 1e7)])
        assert cell is not None
        flat = (cell[0] * grid.ny + cell[1]) * grid.npsi + cell[2]
        misses += flat != d.cell
    assert judged.estimation_misses == misses
    # Hull contact agrees with the summary's independent clearance series.
    assert (judged.hull_contacts == 0) == (outcome.summary.hull_contacts == 0)


def test_the_judge_sees_a_dropped_decision_and_a_displaced_interval(
    coarse_run: tuple[SimRunSpec, SimOutcome, MemoryLog]
) -> None:
    _, outcome, log = coarse_run
    t_s, eta = _eta(outcome)
    decisions = list(log.decisions)
    # Drop the sixth decision: the fifth interval is then held 2 tau = 4 s.
    dropped = decisions[:5] + decisions[6:]
    late = judge_run(outcome.scenario, dropped, outcome.controllers, t_s, eta)
    assert late.late_intervals == 1
    assert late.worst_late_s == pytest.approx(2.0)
    # Push the true path 2 m off in y for one second of the third interval: farther than
    # any tube of a 2-s interval reaches (at most 0.45 m of travel plus margins and cells).
    d = decisions[2]
    contract = DecisionContract.of(
        outcome.controllers[1],
        _cell(outcome, d.cell),
        d.chosen_index,
    )
    r0 = round(d.t_ns / 1e7)
    moved = eta.copy()
    moved[r0 + 50 : r0 + 150, 1] += 2.0
    judged = judge_run(outcome.scenario, decisions, outcome.controllers, t_s, moved)
    base = judge_run(outcome.scenario, decisions, outcome.controllers, t_s, eta)
    assert judged.tube_exits == base.tube_exits + 1
    expected = float(contract.tube_distance_m(moved[r0 + 50 : r0 + 150]).max())
    assert judged.worst_tube_exit_m == pytest.approx(max(expected, base.worst_tube_exit_m))
    assert expected > 2.0 - 1.0  # the tube is well under 1 m tall


# ---------------------------------------------------------------- moving starts


def test_a_moving_start_moves_the_plant_and_the_estimate(
    coarse_run: tuple[SimRunSpec, SimOutcome, MemoryLog]
) -> None:
    _, outcome, log = coarse_run
    truth = outcome.sim.truth()
    np.testing.assert_allclose(truth[0, 1 + TR_NU : 1 + TR_NU + 3], (0.1, -0.05, 0.1))
    # The EKF starts from it: surge and yaw rate right at the first estimate (sway takes
    # the pose noise of the first few samples harder).
    _, _, nu_hat = log.estimates[0]
    true_nu = truth[5, 1 + TR_NU : 1 + TR_NU + 3]
    np.testing.assert_allclose(nu_hat[[0, 2]], true_nu[[0, 2]], atol=0.005)


def test_a_start_velocity_round_trips_and_old_specs_start_at_rest() -> None:
    spec = SimRunSpec(scenario="coarse", seed=4, start=(3.0, 1.0, 0.5),
                      start_velocity=(0.1, 0.0, -0.2))
    assert spec_from_json(spec_to_json(spec)) == replace(spec, loop=LoopConfig())
    at_rest = replace(spec, start_velocity=None)
    assert "start_velocity" not in spec_to_json(at_rest)  # recorded specs stay as they were
    assert spec_from_json(spec_to_json(at_rest)).start_velocity is None


def test_a_total_sums_counts_and_keeps_the_worst() -> None:
    a = GuaranteeViolations(intervals=3, tube_exits=1, worst_tube_exit_m=0.2)
    b = GuaranteeViolations(intervals=4, tube_exits=2, hull_contacts=1, worst_tube_exit_m=0.1)
    total = GuaranteeViolations.total([a, b])
    assert (total.intervals, total.tube_exits, total.hull_contacts) == (7, 3, 1)
    assert total.worst_tube_exit_m == 0.2
    assert total.violations == 4


# ---------------------------------------------------------------- GUARANTEE.md, item 3

COUNTEREXAMPLE = (1.6171, 0.9509, 2.3187)
CRUISE = (-0.1, 0.1, 0.1)
FORCED = (np.array(CRUISE), np.array([0.2, 0.1, 0.0]))
# The audit ran with the margin shipped then; the counterexample is pinned to it.
AUDIT_MARGIN = {"surge_mps": 0.0106, "sway_mps": 0.0216, "yaw_rate_radps": 0.0382}


def _arc_back(pose: tuple[float, float, float], nu: tuple[float, float, float],
              t_s: float) -> tuple[float, float, float]:
    """The pose `t_s` seconds earlier on the exact arc of constant nu (r != 0)."""
    x, y, psi = pose
    u, v, r = nu
    p0 = psi - r * t_s
    x0 = x - (u * (math.sin(psi) - math.sin(p0)) + v * (math.cos(psi) - math.cos(p0))) / r
    y0 = y - (-u * (math.cos(psi) - math.cos(p0)) + v * (math.sin(psi) - math.sin(p0))) / r
    return (x0, y0, p0)


def _exact_arc(pose: FloatArray, nu: FloatArray, t: FloatArray) -> FloatArray:
    """Poses (T, 3) holding nu (3,) from pose (3,) over times t (T,), straight (r = 0) only."""
    assert nu[2] == 0.0
    c, s = math.cos(pose[2]), math.sin(pose[2])
    x = pose[0] + (nu[0] * c - nu[1] * s) * t
    y = pose[1] + (nu[0] * s + nu[1] * c) * t
    return np.column_stack([x, y, np.full_like(t, pose[2])])


def _audit_scenario(tmp_path: Path) -> Path:
    """The paper scenario with the margin the audit ran (GUARANTEE.md, at c1d91af)."""
    head, margin = (Path(hil.scenarios.__file__).parent / "paper.toml").read_text().split(
        "[margin]"
    )
    for key, value in AUDIT_MARGIN.items():
        margin = re.sub(rf"^{key} = .*$", f"{key} = {value}", margin, count=1, flags=re.M)
    text = f"{head}[margin]{margin}"
    path = tmp_path / "paper-audit.toml"
    path.write_text(text)
    return path


def test_the_audit_counterexample_is_flagged_on_the_true_state(tmp_path: Path) -> None:
    # The first decision comes one loop tick (50 ms) after the start: start that much
    # earlier on the cruise arc so the vessel decides where the audit put it.
    start = _arc_back(COUNTEREXAMPLE, CRUISE, 0.05)
    spec = SimRunSpec(scenario=str(_audit_scenario(tmp_path)), seed=0, start=start,
                      start_velocity=CRUISE,
                      loop=LoopConfig(resynthesis_period_s=None, max_duration_s=4.5))
    listed: list[bool] = []

    def forced(safe: FloatArray, previous: FloatArray) -> int:
        n = len(listed)
        if n >= len(FORCED):
            return select_index(safe, previous)
        hit = np.flatnonzero(np.all(np.isclose(safe, FORCED[n]), axis=1))
        listed.append(hit.size > 0)
        return int(hit[0]) if hit.size else select_index(safe, previous)

    log = MemoryLog()
    outcome = simulate(spec, log=log, select=forced)
    # Both inputs were listed safe where the audit says: values 22, then 21.
    assert listed == [True, True]
    first, second = log.decisions[:2]
    assert (first.value, second.value) == (22.0, 21.0)
    t_s, eta = _eta(outcome)
    r1 = round(second.t_ns / 1e7)
    np.testing.assert_allclose(eta[r1], (1.6338, 0.6691, 2.5171), atol=0.005)
    # The second interval's exact arc stays above y = 0.669 (above inflated O1, whose
    # top edge is y = 0.5 for x in [1.25, 2.75]) ...
    controller = outcome.controllers[1]
    grid = controller.grid
    cell = grid.cell_of(eta[r1])
    assert cell is not None
    contract = DecisionContract.of(controller, cell, second.chosen_index)
    arc = _exact_arc(eta[r1], FORCED[1], np.linspace(0.0, 2.0, 201))
    assert arc[:, 1].min() > 0.66
    assert contract.in_tube(arc).all()
    assert contract.in_successor(arc[-1:]).all()
    # ... while the real loop, flown in the simulator, dips into it.
    span = eta[r1 : r1 + 201]
    assert span[:, 1].min() < 0.5
    assert np.all((span[:, 0] > 1.25) & (span[:, 0] < 2.75))
    assert not contract.in_tube(span).all()
    judged = judge_outcome(spec, outcome, log.decisions)
    assert judged.tube_exits >= 1
    assert judged.inflated_obstacle >= 1
    assert judged.worst_inflated_depth_m >= 0.5 - span[:, 1].min() - 1e-9
    assert judged.worst_tube_exit_m > 0.05
    # Judged alone, the first (cruise) interval keeps its contract.
    alone = judge_run(outcome.scenario, log.decisions[:1], outcome.controllers, t_s[: r1 + 1],
                      eta[: r1 + 1])
    assert (alone.tube_exits, alone.successor_misses, alone.inflated_obstacle) == (0, 0, 0)
