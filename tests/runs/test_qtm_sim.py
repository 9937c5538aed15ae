"""End to end: the coarse scenario's stack docks with its pose from QTM over TCP.

The simulated vessel's true pose feeds the test QTM server (through the lab transform, in
mm and a rotation matrix, stamped with QTM's clock); the stack reads it with the ``qtm``
backend over TCP loopback, the IMU and thrusters stay on the simulator. Camera and world
run in lockstep on simulated time (:class:`LockstepClock`): when the loop sleeps to its
next tick the world is integrated to it, the server sends the frames due by then, and the
sleep ends once the backend has received them, as the simulated pose sensor delivers its
samples at the next poll. So the run is as fast as a simulated one and does not depend on
how busy the machine is.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from hil.adapters.frames import ArenaTransform
from hil.adapters.qtm import QtmConfig, QtmPoseSource
from hil.adapters.sim import SimWorld
from hil.core.clock import NS_PER_S
from hil.core.geometry import wrap_angle
from hil.core.samples import Frame, PoseSample
from hil.runs.campaign import StartRegion, draw_starts, first_decision_s
from hil.runs.guarantee import judge_outcome, judged_run
from hil.runs.sim_run import RecordingSolver, SimOutcome, SimRunSpec, sim_config, summarize
from hil.runs.stack_assembly import build_runtime, synthesizer_for
from hil.runs.summary import RunSummary
from hil.runtime.assembly import LayoutSolver, layout_from_scenario
from hil.runtime.loop import World
from hil.runtime.resynthesis import ResynthesisMode
from hil.runtime.settings import LoopConfig
from hil.runtime.trace import MemoryLog
from hil.scenarios import load_scenario
from hil.sim.plant import TR_ETA
from tests.adapters.qtm_server import Faults, QtmTestServer

pytest.importorskip("qtm_rt")

TRANSFORM = ArenaTransform(origin_north_m=2.0, origin_east_m=-1.5, yaw_rad=0.4,
                           body_offset_x_m=0.05)
RATE_HZ = 100.0


class LockstepClock:
    """Simulated time shared by the world, the QTM server and the backend's arrivals.

    Args:
        sim: The simulated world.
        server: A stepped QTM server whose camera shows :meth:`true_lab_pose`.
    """

    def __init__(self, sim: SimWorld, server: QtmTestServer) -> None:
        self._sim = sim
        self._server = server
        self.source: QtmPoseSource | None = None

    def now_ns(self) -> int:
        return self._sim.clock.now_ns()

    def sleep_until(self, t_ns: int) -> None:
        self._sim.clock.sleep_until(t_ns)
        t_s = self._sim.clock.now_ns() / NS_PER_S
        self._server.advance_to(t_s)
        assert self._server.wait_sent(t_s)
        deadline = time.monotonic() + 5.0
        assert self.source is not None
        while (self.source.counters.frames < self._server.log.frames_sent
               and time.monotonic() < deadline):
            time.sleep(0.0002)

    def true_lab_pose(self, t_s: float) -> tuple[float, float, float]:
        """Return the mocap body's lab pose at simulated time `t_s` (s), between physics steps
        interpolated (the last step to the current state)."""
        truth = self._sim.truth()
        times = np.append(truth[:, 0], self._sim.clock.now_ns() / NS_PER_S)
        eta = np.vstack([truth[:, 1 + TR_ETA : 1 + TR_ETA + 3], self._sim.eta])
        k = min(max(int(np.searchsorted(times, t_s, side="right")) - 1, 0), len(times) - 1)
        if k == len(times) - 1:
            x, y, psi = eta[k]
        else:
            w = (t_s - times[k]) / (times[k + 1] - times[k])
            x, y = (1 - w) * eta[k, :2] + w * eta[k + 1, :2]
            psi = eta[k, 2] + w * wrap_angle(float(eta[k + 1, 2] - eta[k, 2]))
        lab = TRANSFORM.to_lab(PoseSample(0, float(x), float(y), wrap_angle(float(psi)),
                                          Frame.ARENA))
        return lab.x_m, lab.y_m, lab.yaw_rad


def pose_errors(poses: list[PoseSample], truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return each pose's position (m) and heading (rad) error against the truth at its stamp."""
    t = np.array([p.t_ns / NS_PER_S for p in poses])
    eta = truth[:, 1 + TR_ETA : 1 + TR_ETA + 3]
    x = np.interp(t, truth[:, 0], eta[:, 0])
    y = np.interp(t, truth[:, 0], eta[:, 1])
    psi = np.interp(t, truth[:, 0], np.unwrap(eta[:, 2]))
    got = np.array([(p.x_m, p.y_m, p.yaw_rad) for p in poses])
    yaw = np.abs((got[:, 2] - psi + np.pi) % (2 * np.pi) - np.pi)
    return np.hypot(got[:, 0] - x, got[:, 1] - y), yaw


def dock_over_qtm(faults: Faults, spec: SimRunSpec | None = None
                  ) -> tuple[RunSummary, MemoryLog, SimWorld, list[str]]:
    """Run the coarse scenario with its pose from the stepped QTM server; return
    (summary, log, world, the feed's event codes)."""
    outcome, log, codes = qtm_outcome(faults, spec)
    return outcome.summary, log, outcome.sim, codes


def qtm_outcome(faults: Faults, spec: SimRunSpec | None = None
                ) -> tuple[SimOutcome, MemoryLog, list[str]]:
    """Run `spec` (default: coarse from its default start) with its pose from the stepped
    QTM server; return the outcome a judge of the true state needs, the log, the codes."""
    spec = spec or SimRunSpec(scenario="coarse", loop=LoopConfig(max_duration_s=80.0))
    scenario = load_scenario(spec.scenario)
    synthesizer = synthesizer_for(scenario, spec.cache_dir)
    sim = SimWorld(sim_config(spec, scenario), max_duration_s=spec.loop.max_duration_s + 10.0)
    clocks: list[LockstepClock] = []
    server = QtmTestServer(lambda t_s: clocks[0].true_lab_pose(t_s), body="2", others=("1",),
                           body_index=1, rate_hz=RATE_HZ, faults=faults, stepped=True)
    clock = LockstepClock(sim, server)
    clocks.append(clock)
    log = MemoryLog()
    solver = RecordingSolver(LayoutSolver(scenario, synthesizer))
    with server:
        config = QtmConfig("127.0.0.1", "2", port=server.port, transform=TRANSFORM)
        with QtmPoseSource(config, clock, on_event=lambda e: log.event(
                e.t_ns, e.level, e.code, e.text)) as source:
            clock.source = source
            assert source.wait_first(5.0)  # the ready gate: QTM streams the body
            world = World(clock, source, sim.imu, sim.obstacles, sim.thrusters)
            runtime = build_runtime(scenario, world, log, spec.loop, synthesizer,
                                    ResynthesisMode.INLINE, solver=solver)
            wall = time.perf_counter()
            stats = runtime.run()
            wall = time.perf_counter() - wall
    summary = summarize(spec, scenario, sim, stats, wall)
    codes = [code for _, _, code, _ in log.events if code.startswith("qtm_")]
    return SimOutcome(summary, scenario, sim, stats, solver.controllers), log, codes


def test_five_starts_dock_over_qtm_as_over_the_sim_backend() -> None:
    """The same five winning starts, docked with the pose from QTM over TCP and with the
    simulated motion capture: every run docks, 0 violations on the true state in both."""
    scenario = load_scenario("coarse")
    solver = LayoutSolver(scenario, synthesizer_for(scenario))
    controller = solver(layout_from_scenario(scenario)).controller
    starts, _ = draw_starts(controller, 5, seed=24, region=StartRegion.of(scenario),
                            settle_s=first_decision_s(LoopConfig()), scenario=scenario)
    rows = []
    for i, start in enumerate(starts):
        spec = SimRunSpec(scenario="coarse", start=start, seed=i,
                          loop=LoopConfig(max_duration_s=80.0))
        sim_summary, sim_violations = judged_run(spec)
        outcome, log, codes = qtm_outcome(Faults(), spec)
        qtm_violations = judge_outcome(spec, outcome, log.decisions)
        rows.append((start, sim_summary, sim_violations, outcome.summary, qtm_violations))
        assert codes == ["qtm_connected"]
    for start, sim_s, sim_v, qtm_s, qtm_v in rows:
        print(f"start {start}: sim docked {sim_s.docked} in {sim_s.duration_s:.1f} s, "
              f"{sim_v.intervals} intervals, {sim_v.violations} violations; qtm docked "
              f"{qtm_s.docked} in {qtm_s.duration_s:.1f} s, {qtm_v.intervals} intervals, "
              f"{qtm_v.violations} violations, {qtm_s.hull_contacts} contacts")
        assert sim_s.docked, (start, sim_s.end_reason)
        assert qtm_s.docked, (start, qtm_s.end_reason)
        assert sim_v.violations == qtm_v.violations == 0, (start, sim_v, qtm_v)
        assert sim_s.hull_contacts == qtm_s.hull_contacts == 0
    # The same campaign figures: docking times alike (the same decisions but for noise).
    sim_mean = float(np.mean([r[1].duration_s for r in rows]))
    qtm_mean = float(np.mean([r[3].duration_s for r in rows]))
    assert abs(qtm_mean - sim_mean) <= 0.25 * sim_mean, (sim_mean, qtm_mean)


def test_coarse_docks_with_the_pose_from_qtm() -> None:
    summary, log, sim, codes = dock_over_qtm(Faults())
    scenario = load_scenario("coarse")
    # Docked (reached and held), judged on the simulator's true state: no contact, the
    # runtime monitor quiet, the pose never stale.
    assert summary.docked, summary.end_reason
    assert summary.hull_contacts == 0
    assert summary.min_clearance_m > 0.0
    assert summary.tube_exits == summary.successor_misses == 0
    assert summary.not_winning_decisions == summary.pose_losses == 0
    assert codes == ["qtm_connected"]
    # QTM's path adds no error: each pose is the truth at its stamp (float32 mm).
    pos_err, yaw_err = pose_errors(log.poses, sim.truth())
    assert len(log.poses) >= 0.99 * RATE_HZ * summary.duration_s
    assert float(pos_err.max()) < 1e-4
    assert float(yaw_err.max()) < 1e-4
    assert float(pos_err.max()) < scenario.transient.estimation_position_m


def test_a_lost_body_holds_the_vessel_and_it_docks_after() -> None:
    # QTM loses the hull for 1 s mid-run: no poses, the runtime's pose timeout (0.5 s)
    # holds the vessel with thrusters at zero, the feed's events say what happened.
    summary, log, _, codes = dock_over_qtm(Faults(nan_s=((12.0, 13.0),)))
    assert summary.docked, summary.end_reason
    assert summary.hull_contacts == 0
    assert summary.pose_losses == 1
    assert codes == ["qtm_connected", "qtm_body_lost", "qtm_body_back"]
    assert not [p for p in log.poses if 12.0 <= p.t_ns / NS_PER_S < 13.0 - 1e-6]
    stale = [text for _, _, code, text in log.events if "pose" in code and "no pose" in text]
    assert stale


def test_drops_and_a_clock_jump_are_events_and_the_stamps_stay_true() -> None:
    # QTM skips 5 frames and its clock leaps 0.3 s ahead mid-run: drops counted, the offset
    # re-estimated at the jump's first frame, every pose still the truth at its stamp.
    drops = frozenset(range(800, 805))
    summary, log, sim, codes = dock_over_qtm(Faults(drop_frames=drops,
                                                    clock_jumps_s=((15.0, 0.3),)))
    assert summary.docked, summary.end_reason
    assert summary.hull_contacts == 0
    assert summary.tube_exits == summary.pose_losses == 0
    assert codes == ["qtm_connected", "qtm_drop", "qtm_clock_jump"]
    texts = [text for _, _, code, text in log.events if code.startswith("qtm_")]
    assert texts[1] == "qtm: 5 frame(s) dropped (800..804)"
    assert texts[2].startswith("qtm: clock offset re-estimated at frame 1500: QTM time leapt")
    pos_err, yaw_err = pose_errors(log.poses, sim.truth())
    assert float(pos_err.max()) < 1e-4
    assert float(yaw_err.max()) < 1e-4
