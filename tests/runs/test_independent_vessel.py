"""Issue 11's outside check: a vessel hil did not write, driven by `hil vessel` over DDS.

`tools/independent_vessel.py` (its own coefficients, dynamics, thrusters and RK45, no
import of hil) publishes pose, IMU and /clock on the lab's topics in the lab's NED
world; `hil vessel` runs the stack against it on the coarse scenario with the arena
rotated and shifted in that world (the config's [ros.transform]); the vessel's own
true state is then held to the guarantee (hull clear of obstacles and inside the arena,
each interval in its tube, ending in its successor cells with a smaller value) by
:func:`hil.replay.truth.judge_log_on_truth`. Each run gets its own ROS_DOMAIN_ID on
loopback; both processes are stopped whatever happens.

Run with ``-s`` to see the measured figures of each run.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.adapters.frames import ArenaTransform
from hil.bag.run_data import load_run
from hil.model.coefficients import ENTERPRISE_I
from hil.model.thrusters import VOYAGER_THRUSTERS
from hil.replay.controllers import ControllerCache
from hil.replay.truth import TruthJudgement, judge_log_on_truth, load_truth
from hil.runs.campaign import StartRegion, draw_starts, draw_velocities
from hil.runtime.assembly import layout_from_scenario
from hil.scenarios import load_scenario
from hil.sim.plant import N_PLANT, N_TRACE, P_ALPHA, P_ETA, P_NU, P_U, plant_advance
from tests.runs.dds_processes import dds_env, stop

pytest.importorskip("rclpy")
pytestmark = pytest.mark.ros

FloatArray = NDArray[np.float64]
ROOT = Path(__file__).resolve().parents[2]
VESSEL = [sys.executable, str(ROOT / "tools" / "independent_vessel.py")]
HIL = [sys.executable, "-m", "hil"]
NS_PER_S = 1_000_000_000
PICKUP_NS = 10_000_000  # the independent vessel applies a command from its next cycle

# The arena in the lab's NED world: its origin 2 m north and 1 m west of the lab's, its
# x axis pointing east. So arena (x, y, psi) is lab (north 2 - y, east -1 + x, psi + 90 deg):
# written out here, not through hil's transform, so that a wrong transform shows.
TRANSFORM = ArenaTransform(origin_north_m=2.0, origin_east_m=-1.0, yaw_rad=math.pi / 2)


def _to_lab(x_m: float, y_m: float, psi_rad: float) -> tuple[float, float, float]:
    return 2.0 - y_m, -1.0 + x_m, math.degrees(psi_rad) + 90.0


class Start(NamedTuple):
    """A run's start: arena pose (m, m, rad) and body velocity (m/s, m/s, rad/s)."""

    pose: tuple[float, float, float]
    velocity: tuple[float, float, float]


class Outcome(NamedTuple):
    summary: dict[str, object]
    judged: TruthJudgement
    truth_csv: Path
    log: Path


@pytest.fixture(scope="module")
def controllers() -> ControllerCache:
    """The coarse scenario's controllers, shared by the judge of every run."""
    return ControllerCache(load_scenario("coarse"))


def _run(tmp_path: Path, start: Start, domain: int, controllers: ControllerCache) -> Outcome:
    """Run the independent vessel and `hil vessel` over DDS; judge on the vessel's truth."""
    config = tmp_path / "vessel.toml"
    config.write_text(f"""
scenario = "coarse"
runs_dir = "{tmp_path / "runs"}"
[ros]
use_sim_time = true
domain_id = {domain}
[ros.transform]
origin_north_m = {TRANSFORM.origin_north_m}
origin_east_m = {TRANSFORM.origin_east_m}
yaw_rad = {TRANSFORM.yaw_rad}
[loop]
max_duration_s = 150.0
resynthesis_period_s = 20.0
""")
    out, truth_csv = tmp_path / "run", tmp_path / "truth.csv"
    vessel_log = tmp_path / "vessel.log"
    err_file = vessel_log.open("wb")  # a file, not a pipe: nobody reads it while it runs
    north, east, yaw_deg = _to_lab(*start.pose)
    u, v, r = start.velocity
    vessel = subprocess.Popen(
        [*VESSEL, f"--start={north},{east},{yaw_deg}",
         f"--start-velocity={u},{v},{math.degrees(r)}", "--clock", "--speed", "2",
         "--lockstep-s", "0.1", "--domain-id", str(domain), "--duration", "400",
         "--seed", str(domain), "--out", str(truth_csv)],
        env=dds_env(domain), stdout=subprocess.DEVNULL, stderr=err_file)
    stack = None
    try:
        stack = subprocess.Popen(
            [*HIL, "vessel", "--config", str(config), "--out", str(out), "--json"],
            env=dds_env(domain), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        stdout, stderr = stack.communicate(timeout=360)
    finally:
        if stack is not None and stack.poll() is None:
            stack.kill()
            stack.wait()
        vessel_rc = stop(vessel)
        err_file.close()
    vessel_err = vessel_log.read_text()
    assert vessel_rc == 0, vessel_err[-2000:]
    assert "released" in vessel_err, vessel_err[-2000:]
    assert stack.returncode == 0, stderr[-3000:] + stdout[-3000:]
    summary = json.loads(stdout.strip().splitlines()[-1])
    judged = judge_log_on_truth(out, load_truth(truth_csv), TRANSFORM, controllers=controllers)
    return Outcome(summary, judged, truth_csv, out)


def _model_gap_m(outcome: Outcome) -> tuple[float, float]:
    """Return how far hil's own plant strays from the independent one in 2 s (max, mean, m).

    Per decision: hil's simulator (its Euler plant and thruster model) is started at the
    independent vessel's true state, its thrusters at the command in force, and fed the
    commands the stack recorded, each from one 10-ms cycle after its stamp (when the
    vessel picks it up), for one command period; the gap is its distance from the
    independent truth at the end.
    """
    run = load_run(outcome.log)
    raw = np.genfromtxt(outcome.truth_csv, delimiter=",", names=True)
    truth = load_truth(outcome.truth_csv).to_arena(TRANSFORM)
    t_ns = truth.t_ns
    nu = np.stack([raw["u_mps"], raw["v_mps"], raw["r_radps"]], axis=1)
    m_inv, coef = ENTERPRISE_I.kernel_arrays()
    tp = VOYAGER_THRUSTERS.as_array()
    cmd_t, cmd = run.thrusters.t_ns, run.thrusters.values
    gaps = []
    for decision in run.decisions:
        k0 = int(np.searchsorted(t_ns, decision.t_ns))
        k1 = k0 + 200
        if k1 >= len(t_ns):
            break
        state = np.zeros(N_PLANT)
        state[P_ETA : P_ETA + 3] = truth.eta[k0]
        state[P_NU : P_NU + 3] = nu[k0]
        j = max(int(np.searchsorted(cmd_t, t_ns[k0] - PICKUP_NS, side="right")) - 1, 0)
        state[P_U : P_U + 3], state[P_ALPHA : P_ALPHA + 2] = cmd[j, :3], cmd[j, 3:5]
        trace = np.empty((1, N_TRACE))
        for k in range(k0, k1):
            j = max(int(np.searchsorted(cmd_t, t_ns[k] - PICKUP_NS, side="right")) - 1, 0)
            plant_advance(m_inv, coef, tp, 0, 0.01, state, cmd[j, :3].copy(),
                          cmd[j, 3:5].copy(), np.zeros((1, 3)), trace)
        gaps.append(float(np.hypot(*(state[P_ETA : P_ETA + 2] - truth.eta[k1, :2]))))
    return max(gaps), float(np.mean(gaps))


def _check(outcome: Outcome, label: str) -> None:
    summary, judged = outcome.summary, outcome.judged
    g = judged.violations
    gap_max, gap_mean = _model_gap_m(outcome)
    ticks = load_run(outcome.log).estimate.t_ns
    stall_s = float(np.diff(ticks).max()) / NS_PER_S
    print(f"\n{label}: docked {summary['docked']} in {summary['docking_time_s']} s, "
          f"{g.intervals} intervals, violations {g.violations} (tube exits {g.tube_exits}, "
          f"worst {g.worst_tube_exit_m:.4f} m; successor misses {g.successor_misses}, worst "
          f"{g.worst_successor_miss_m:.4f} m; value not decreasing {g.value_not_decreasing}; "
          f"hull contacts {g.hull_contacts}; outside {g.hull_outside_arena}), late "
          f"{g.late_intervals} (longest loop gap {stall_s:.2f} s), estimation misses "
          f"{g.estimation_misses} (worst {g.worst_estimation_m * 1000:.1f} mm); "
          f"received pose vs truth {judged.pose_offset_m * 1000:.1f} mm / "
          f"{math.degrees(judged.heading_offset_rad):.2f} deg; hil's plant from the true "
          f"state over 2 s: {gap_mean * 1000:.1f} mm mean, {gap_max * 1000:.1f} mm max")
    assert summary["docked"] is True
    assert judged.unjudged == ()
    assert g.intervals >= 10
    assert g.violations == 0, g
    # The truth lies where the stack saw the vessel, up to mocap noise (1 mm, 0.1 deg):
    # frames, transform and clock agree.
    assert judged.pose_offset_m < 0.01
    assert judged.heading_offset_rad < math.radians(1.0)
    # The two models agree on what the same commands do (their code shares nothing).
    assert gap_mean < 0.03
    # Docked on the true state too: the last true pose is in the real target.
    scenario = load_scenario("coarse")
    x, y, _ = load_truth(outcome.truth_csv).to_arena(TRANSFORM).eta[-1]
    corners = scenario.target.shape.vertices()
    assert corners[:, 0].min() <= x <= corners[:, 0].max(), (x, y)
    assert corners[:, 1].min() <= y <= corners[:, 1].max(), (x, y)


def _domain(offset: int) -> int:
    return 60 + (os.getpid() + 13 * offset) % 80


def test_a_moving_start_docks_within_the_guarantee_on_the_independent_truth(
        tmp_path: Path, controllers: ControllerCache) -> None:
    # Below O2, bow up-left, already moving forward, drifting to port and turning.
    start = Start((0.25, -1.2, math.radians(120.0)), (0.1, -0.05, 0.1))
    _check(_run(tmp_path, start, _domain(0), controllers), "moving (0.25, -1.2, 120 deg)")


@pytest.mark.slow
@pytest.mark.parametrize("pose", [(0.0, -1.0, math.pi), (0.25, -0.75, math.pi / 2)],
                         ids=["rest-0,-1,180", "rest-0.25,-0.75,90"])
def test_starts_at_rest_dock_within_the_guarantee_on_the_independent_truth(
        tmp_path: Path, controllers: ControllerCache, pose: tuple[float, float, float]) -> None:
    _check(_run(tmp_path, Start(pose, (0.0, 0.0, 0.0)), _domain(1), controllers),
           f"at rest {pose}")


@pytest.mark.slow
@pytest.mark.parametrize("index", [0, 1])
def test_random_winning_starts_dock_within_the_guarantee_on_the_independent_truth(
        tmp_path: Path, controllers: ControllerCache, index: int) -> None:
    # As `hil campaign` draws them: winning at the first decision, half of them moving.
    scenario = load_scenario("coarse")
    controller = controllers(layout_from_scenario(scenario)).controller
    velocities = [None, draw_velocities(scenario, 1, 1.0, seed=11)[0]]  # at rest, moving
    starts, _ = draw_starts(controller, 2, seed=11, region=StartRegion.of(scenario),
                            velocities=velocities, scenario=scenario)
    velocity = velocities[index] or (0.0, 0.0, 0.0)
    _check(_run(tmp_path, Start(starts[index], velocity), _domain(2 + index), controllers),
           f"random start {tuple(round(v, 3) for v in starts[index])}, velocity {velocity}")
