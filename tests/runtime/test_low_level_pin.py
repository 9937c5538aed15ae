"""The real runtime against the compiled closed loop, tick for tick, on fixed references.

The runtime (:class:`hil.runtime.loop.Runtime`) drives the simulated world
(:class:`hil.adapters.sim.SimWorld`) with the vessel's low level; a scripted symbolic
controller issues a fixed reference sequence every 2 s and the observer hands on the
world's true velocity. The compiled loop of :mod:`hil.sim.closed_loop` with the same
references, start and no sensors must give the same thruster commands, forces and
trajectory. (With the EKF the two differ by design: the world's IMU reads the
acceleration of the coming step and its pose sensor draws its own noise and delays,
so only the deterministic part is pinned here.)
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hil.adapters.sim import SimConfig, SimWorld
from hil.core.samples import ImuSample, ObstacleLayout, PoseSample
from hil.runtime.assembly import low_level_for
from hil.runtime.loop import Runtime, World
from hil.runtime.resynthesis import ResynthesisMode, Resynthesizer
from hil.runtime.settings import LoopConfig
from hil.runtime.trace import MemoryLog
from hil.sim.closed_loop import LowLevelConfig, simulate_closed_loop
from hil.sim.plant import P_NU
from tests.runtime.scripted import ScriptedController

F = NDArray[np.float64]

REFS = np.array(
    [[0.1, 0.0, 0.0], [0.15, 0.05, 0.1], [0.2, -0.1, -0.2], [0.0, 0.1, 0.2], [-0.1, 0.0, 0.0]]
)
START = (2.0, 1.0, 0.5)


class TrueVelocity:
    """An observer that reports the world's true state (no filter)."""

    def __init__(self, world: SimWorld) -> None:
        self.world = world

    def update_pose(self, sample: PoseSample) -> bool:
        """Accept every pose (it keeps the loop's pose watchdog fed)."""
        return True

    def update_imu(self, sample: ImuSample) -> bool:
        """Accept every IMU sample."""
        return True

    def breach(self) -> None:
        """Never: the truth is consistent."""

    def estimate(self) -> tuple[F, F]:
        """Return the true (eta, nu) at the clock's time."""
        return self.world.eta, self.world.state[P_NU : P_NU + 3].copy()


def run_runtime(refs: F) -> tuple[MemoryLog, SimWorld, ScriptedController]:
    """Run the real loop for len(refs) decision periods; return its log and world."""
    world = SimWorld(SimConfig(start=START, seed=3), max_duration_s=2.0 * len(refs) + 5.0)
    controller = ScriptedController(refs)

    def solve(layout: ObstacleLayout, report_age_s: float) -> ScriptedController:
        return controller

    # Stop at the tick that would start decision len(refs) (ticks every 50 ms).
    # The observer is exact (no filter to settle): decide at the first tick, as the
    # compiled loop does.
    loop = LoopConfig(
        resynthesis_period_s=None, max_duration_s=2.0 * len(refs) - 0.025, observer_settle_s=0.0
    )
    log = MemoryLog()
    runtime = Runtime(
        World(world.clock, world.pose, world.imu, world.obstacles, world.thrusters),
        TrueVelocity(world),
        low_level_for(loop.loop_hz),
        Resynthesizer(solve, ResynthesisMode.INLINE),
        lambda options: 0,
        log,
        loop,
    )
    runtime.run()
    return log, world, controller


def test_runtime_low_level_equals_compiled_loop() -> None:
    log, world, controller = run_runtime(REFS)
    res = simulate_closed_loop(REFS, LowLevelConfig(observer=None), eta0=np.array(START))
    assert controller.decisions == len(REFS)

    # The runtime sends one command per 50-ms tick, plus the zero command at the end.
    ticks = [c for c in log.thruster_commands if c.t_ns < 2_000_000_000 * len(REFS)]
    assert len(ticks) == res.t_s.size // 5
    sent = np.array([[c.tunnel, c.port, c.starboard] for c in ticks])
    angles = np.array([[c.port_angle_rad, c.starboard_angle_rad] for c in ticks])
    np.testing.assert_allclose(sent, res.setpoints[::5], atol=1e-9, rtol=0)
    np.testing.assert_allclose(angles, res.setpoint_angles_rad[::5], atol=1e-9, rtol=0)
    # (Up to the time limit: the run then brakes to rest, which the compiled loop does not.)
    end_ns = 2_000_000_000 * len(REFS)
    forces = np.array([f for t, f in log.forces if t < end_ns])
    np.testing.assert_allclose(forces, res.tau_cmd[::5], atol=1e-9, rtol=0)
    refs_sent = np.array([r for t, r in log.velocity_references if t < end_ns])
    np.testing.assert_array_equal(refs_sent, res.nu_ref[::5])

    # The world integrated the same trajectory under those commands.
    truth = world.truth()[: res.t_s.size]
    np.testing.assert_allclose(truth[:, 0], res.t_s, atol=1e-12)
    np.testing.assert_allclose(truth[:, 1:4], res.eta, atol=1e-9, rtol=0)
    np.testing.assert_allclose(truth[:, 4:7], res.nu, atol=1e-9, rtol=0)
    # And it tracked: the comparison is not between two idle vessels.
    assert np.abs(res.nu[-1] - REFS[-1]).max() < 0.02
