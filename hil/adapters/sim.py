"""The simulated backend: the vessel simulator with its sensors, behind the adapters.

A :class:`SimWorld` owns the plant (hull + thrusters, :mod:`hil.sim.plant`),
the pose and IMU sensor models and the obstacle schedule. Its clock is a
:class:`~hil.core.clock.SimClock`: when the loop sleeps, the world integrates
the plant over that span at the physics rate, with the last thruster command
held, and queues the sensor samples that fall due. Everything is seeded, so a
run repeats exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hil.adapters.interfaces import ThrusterSinkError
from hil.core.arrays import FloatArray
from hil.core.clock import NS_PER_S, SimClock
from hil.core.motion import ObstacleMotion as ObstacleMotion  # re-exported: SimConfig's motions
from hil.core.motion import displacements_m
from hil.core.samples import (
    ImuSample,
    ObstacleLayout,
    PoseSample,
    ThrusterCommand,
)
from hil.core.shapes import Rect
from hil.model.coefficients import ENTERPRISE_I, VesselParams
from hil.model.dynamics import Integrator
from hil.model.environment import EnvironmentalLoad
from hil.model.thrusters import VOYAGER_THRUSTERS, ThrusterParams
from hil.model.vessel import Vessel
from hil.sim.plant import (
    N_PLANT,
    N_TRACE,
    P_ALPHA,
    P_ETA,
    P_NU,
    TR_ETA,
    TR_NU,
    TR_NU_DOT,
    plant_advance,
)
from hil.sim.sensors import ImuSensorConfig, PoseSensorConfig, SimulatedImu, SimulatedPoseSensor


@dataclass(frozen=True, slots=True)
class ThrusterOutage:
    """A span in which the thruster link fails (commands raise ThrusterSinkError).

    Attributes:
        start_s: Start of the outage (s).
        stop_s: End of the outage (s).
    """

    start_s: float
    stop_s: float


@dataclass(frozen=True)
class SimConfig:
    """The simulated world.

    Attributes:
        start: Initial pose (x m, y m, psi rad).
        start_velocity: Initial body velocity (u m/s, v m/s, r rad/s); at rest by default.
        seed: Seed of every random stream (sensor noise, dropouts, loads).
        vessel: Hull coefficients.
        thrusters: Thruster geometry, gains and limits.
        dt_s: Physics step (s); 0.01 s as in the paper.
        integrator: Forward Euler (the paper's) or RK4.
        pose: Pose sensor model.
        imu: IMU model.
        load: Environmental load b(t).
        obstacles: Real obstacles at t = 0.
        motions: Scheduled obstacle motions (:class:`~hil.core.motion.ObstacleMotion`);
            motions of one obstacle add up.
        obstacle_report_period_s: How often the obstacles' positions are reported when
            motions are scheduled (s).
        thruster_outages: Spans of thruster-link failure (fault injection).
        loop_stalls_s: Spans (start_s, duration_s) in which the loop sleeping on this
            world's clock cannot run (fault injection: the clock's ``stalls_ns``); the
            vessel moves on under the last command.
    """

    start: tuple[float, float, float]
    start_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    seed: int = 0
    vessel: VesselParams = ENTERPRISE_I
    thrusters: ThrusterParams = VOYAGER_THRUSTERS
    dt_s: float = 0.01
    integrator: Integrator = Integrator.EULER
    pose: PoseSensorConfig = field(default_factory=PoseSensorConfig)
    imu: ImuSensorConfig = field(default_factory=ImuSensorConfig)
    load: EnvironmentalLoad = field(default_factory=EnvironmentalLoad)
    obstacles: tuple[Rect, ...] = ()
    motions: tuple[ObstacleMotion, ...] = ()
    obstacle_report_period_s: float = 1.0
    thruster_outages: tuple[ThrusterOutage, ...] = ()
    loop_stalls_s: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        if len(self.start) != 3 or not all(math.isfinite(v) for v in self.start):
            raise ValueError(f"start must be a finite (x, y, psi), got {self.start!r}")
        if len(self.start_velocity) != 3 or not all(math.isfinite(v) for v in self.start_velocity):
            raise ValueError(
                f"start_velocity must be a finite (u, v, r), got {self.start_velocity!r}")
        for motion in self.motions:
            if not 0 <= motion.index < len(self.obstacles):
                raise ValueError(f"obstacle motion names obstacle {motion.index!r}, "
                                 f"but there are {len(self.obstacles)}")
        for start_s, duration_s in self.loop_stalls_s:
            if not (math.isfinite(start_s) and math.isfinite(duration_s) and duration_s > 0):
                raise ValueError(
                    f"a loop stall needs a finite start and a duration > 0 s, got "
                    f"({start_s!r}, {duration_s!r})"
                )
        if not self.obstacle_report_period_s > 0:
            raise ValueError("obstacle_report_period_s must be positive, "
                             f"got {self.obstacle_report_period_s!r}")


class _PendingSamples:
    """Samples produced by the world and not yet polled by the stack."""

    def __init__(self) -> None:
        self.poses: list[PoseSample] = []
        self.imus: list[ImuSample] = []


class SimPoseSource:
    """Pose samples from the simulated motion-capture system."""

    def __init__(self, inbox: _PendingSamples) -> None:
        self._inbox = inbox

    def poll(self) -> list[PoseSample]:
        """Return the poses delivered since the last call, oldest first."""
        out, self._inbox.poses = self._inbox.poses, []
        return out


class SimImuSource:
    """IMU samples from the simulated IMU."""

    def __init__(self, inbox: _PendingSamples) -> None:
        self._inbox = inbox

    def poll(self) -> list[ImuSample]:
        """Return the IMU samples delivered since the last call, oldest first."""
        out, self._inbox.imus = self._inbox.imus, []
        return out


class SimObstacleSource:
    """The obstacle layout over simulated time: with motions scheduled, a tracker.

    A world with motions reports every obstacle's position every
    ``obstacle_report_period_s``, moved or not (a tracker re-reports still obstacles too,
    so their reports stay fresh), each displaced by the sum of its motions
    (:func:`~hil.core.motion.displacements_m`) at the report's time; a world without
    keeps the layout of t = 0.
    """

    def __init__(self, world: SimWorld) -> None:
        self._world = world
        self._layout = ObstacleLayout(0, world.config.obstacles)

    def latest(self) -> ObstacleLayout:
        """Return the newest reported layout, stamped with its report time."""
        cfg = self._world.config
        period_ns = round(cfg.obstacle_report_period_s * NS_PER_S)
        t_ns = (self._world.clock.now_ns() // period_ns) * period_ns
        if not cfg.motions or t_ns == self._layout.t_ns:
            return self._layout
        offsets = displacements_m(cfg.motions, len(cfg.obstacles), t_ns / NS_PER_S)[:, 0]
        moved = {m.index for m in cfg.motions}
        self._layout = ObstacleLayout(t_ns, tuple(
            o.translate(float(offsets[n, 0]), float(offsets[n, 1])) if n in moved else o
            for n, o in enumerate(cfg.obstacles)))
        return self._layout


class SimThrusterSink:
    """Hands thruster commands to the simulated plant."""

    def __init__(self, world: SimWorld) -> None:
        self._world = world

    def send(self, command: ThrusterCommand) -> None:
        """Set the plant's command setpoint; fails inside a scheduled outage."""
        t_s = self._world.clock.now_ns() / NS_PER_S
        for outage in self._world.config.thruster_outages:
            if outage.start_s <= t_s < outage.stop_s:
                raise ThrusterSinkError(f"simulated thruster link outage at t={t_s:.2f} s")
        self._world.u_set[:] = (command.tunnel, command.port, command.starboard)
        self._world.alpha_set[:] = (command.port_angle_rad, command.starboard_angle_rad)


class SimWorld:
    """The simulated C/S Voyager in its arena, seen through the adapters.

    Args:
        config: The world: start pose, seed, models and faults.
        max_duration_s: Longest run this world supports (sizes the load series).
    """

    def __init__(self, config: SimConfig, max_duration_s: float = 900.0) -> None:
        self.config = config
        vessel = Vessel(config.vessel, config.dt_s, config.integrator)
        self._m_inv, self._coef = vessel.params.kernel_arrays()
        self._tp = config.thrusters.as_array()
        self._dt_ns = round(config.dt_s * NS_PER_S)
        self._max_steps = math.ceil(max_duration_s / config.dt_s) + 1
        # A zero load (the default) needs no series, so a long-running node costs no memory.
        self._load: FloatArray | None = None
        if config.load != EnvironmentalLoad():
            self._load = np.ascontiguousarray(config.load.series(self._max_steps, config.dt_s))
        self.state = np.zeros(N_PLANT)
        self.state[P_ETA : P_ETA + 3] = config.start
        self.state[P_NU : P_NU + 3] = config.start_velocity
        self.state[P_ALPHA : P_ALPHA + 2] = (math.pi / 2, -math.pi / 2)
        self.u_set = np.zeros(3)
        self.alpha_set = np.array([math.pi / 2, -math.pi / 2])
        self._step = 0
        self._pose_every = self._every(config.pose.rate_hz)
        self._imu_every = self._every(config.imu.rate_hz)
        # Separate streams per sensor, all derived from the world's seed.
        seeds = np.random.SeedSequence(config.seed).generate_state(2)
        self._pose_sensor = SimulatedPoseSensor(config.pose, seed=int(seeds[0]))
        self._imu = SimulatedImu(config.imu, seed=int(seeds[1]))
        self._inbox = _PendingSamples()
        self._truth: list[FloatArray] = []
        stalls = tuple(
            (round(a * NS_PER_S), round((a + d) * NS_PER_S)) for a, d in config.loop_stalls_s
        )
        self.clock = SimClock(0, self._advance, stalls)
        self.pose = SimPoseSource(self._inbox)
        self.imu = SimImuSource(self._inbox)
        self.obstacles = SimObstacleSource(self)
        self.thrusters = SimThrusterSink(self)

    def _every(self, rate_hz: float) -> int:
        steps = round(1.0 / (rate_hz * self.config.dt_s))
        if steps < 1 or abs(steps * rate_hz * self.config.dt_s - 1.0) > 1e-6:
            raise ValueError(f"sensor rate {rate_hz!r} Hz is not a whole number of "
                             f"physics steps of {self.config.dt_s!r} s")
        return steps

    @property
    def eta(self) -> FloatArray:
        """The true pose (x, y, psi), shape (3,)."""
        return self.state[P_ETA : P_ETA + 3].copy()

    def truth(self) -> FloatArray:
        """Return the true trajectory so far, shape (N, 1 + N_TRACE): t_s, eta, nu, nu_dot, tau."""
        if not self._truth:
            return np.zeros((0, 1 + N_TRACE))
        return np.concatenate(self._truth)

    def _advance(self, _t_from_ns: int, t_to_ns: int) -> None:
        first = self._step
        last = t_to_ns // self._dt_ns
        n = last - first
        if n <= 0:
            return
        if last >= self._max_steps:
            raise RuntimeError(f"simulated world ran past its maximum duration at t={t_to_ns} ns")
        load = np.zeros((n, 3)) if self._load is None else self._load[first:last]
        trace = np.empty((n, N_TRACE))
        plant_advance(self._m_inv, self._coef, self._tp, int(self.config.integrator),
                      self.config.dt_s, self.state, self.u_set, self.alpha_set, load, trace)
        for i in range(n):
            k = first + i
            t_ns = k * self._dt_ns
            if k % self._pose_every == 0:
                pose = self._pose_sensor.measure(t_ns, trace[i, TR_ETA : TR_ETA + 3])
                if pose is not None:
                    self._inbox.poses.append(pose)
            if k % self._imu_every == 0:
                self._inbox.imus.append(self._imu.measure(
                    t_ns, trace[i, TR_NU : TR_NU + 3], trace[i, TR_NU_DOT : TR_NU_DOT + 3]))
        times = (np.arange(first, last) * self.config.dt_s)[:, None]
        self._truth.append(np.hstack([times, trace]))
        self._step = last
