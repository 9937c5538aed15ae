"""One docking run in simulation: a pure function of (scenario, seed, start, options).

`run_in_sim` builds the simulated world and the stack, runs the loop in
simulated time, and returns a :class:`~hil.runs.summary.RunSummary` that
judges the run by the simulator's ground truth (hull clearance to the real
obstacles, tracking error of the true velocity). Everything it takes is
picklable, so a campaign can map it over processes.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import nullcontext
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from hil.adapters.sim import ObstacleMotion, SimConfig, SimWorld, ThrusterOutage
from hil.bag.recorder import Recorder
from hil.bag.run_info import RunInfo
from hil.controllers.pid import PidGains
from hil.controllers.symbolic import (
    Controller,
    ControllerSources,
    Select,
    SymbolicAdapter,
    wait_slowest,
)
from hil.core.clock import NS_PER_S
from hil.core.codec import from_jsonable, to_jsonable
from hil.core.motion import displacements_m
from hil.core.samples import ObstacleLayout
from hil.model.environment import EnvironmentalLoad
from hil.runs.policies import policy
from hil.runs.stack_assembly import (
    build_runtime,
    default_start,
    scenario_hash,
    synthesizer_for,
)
from hil.runs.summary import RunSummary, summarize_run
from hil.runtime.assembly import LayoutSolver, layout_from_scenario
from hil.runtime.controller_lru import ControllerLru
from hil.runtime.loop import World
from hil.runtime.protocols import RunLog
from hil.runtime.resynthesis import ResynthesisMode
from hil.runtime.settings import LoopConfig
from hil.runtime.signals import stop_on_signals
from hil.runtime.stats import RunStats
from hil.runtime.trace import MemoryLog
from hil.scenarios import Scenario, load_scenario
from hil.sim.plant import TR_ETA, TR_NU
from hil.sim.sensors import PoseSensorConfig


@dataclass(frozen=True)
class SimRunSpec:
    """Everything that defines one simulated run.

    Attributes:
        scenario: Packaged scenario name or path to a TOML file.
        seed: Seed of the world's random streams.
        start: Initial pose (x m, y m, psi rad); None takes the scenario's default.
        start_velocity: Initial body velocity (u m/s, v m/s, r rad/s) of the vessel, which
            the EKF starts from too; None starts at rest.
        out_dir: Record the run as a bag in this new directory; None keeps it in memory.
        loop: Loop timing and fault thresholds.
        pose_outages_s: Injected pose outages as (start_s, duration_s).
        loop_stalls_s: Injected stalls of the control loop as (start_s, duration_s): it
            does not tick meanwhile, the vessel moving on under the last command.
        thruster_outages: Injected thruster-link failures.
        motions: Scheduled obstacle motions besides the scenario's ``[[simulated_motion]]``
            (see :func:`world_motions`).
        cache_dir: Abstraction-table cache (None: the default cache).
        gains: Velocity-PID gains of the low level; None: the shipped ones (those the
            scenario's deviation budget was measured with).
        load: Environmental load b(t) on the simulated vessel (its Gauss-Markov noise
            seeded by the load's own seed); None: calm water, as in the tank.
        select: The policy choosing among the listed safe inputs
            (:data:`~hil.runs.policies.POLICIES`): the paper's "J", or an adversary's.
        synthesis_latency_s: Each synthesis takes this long on the simulated clock, one
            at a time, as a slower solver beside the loop would (s; 0: at once). The
            simulation of a vessel whose solver is slower than its obstacle reports.
        pose_noise_scale: The simulated motion capture's noise stds times this (> 0; 1:
            the defaults, 1 mm and 0.1 deg, which the EKF and the estimation bound
            assume). Above 1 the estimation premise breaks: the run for the
            consistency watch (:mod:`hil.controllers.consistency`).
    """

    scenario: str = "paper"
    seed: int = 0
    start: tuple[float, float, float] | None = None
    out_dir: Path | None = None
    start_velocity: tuple[float, float, float] | None = None
    loop: LoopConfig = field(default_factory=LoopConfig)
    pose_outages_s: tuple[tuple[float, float], ...] = ()
    loop_stalls_s: tuple[tuple[float, float], ...] = ()
    thruster_outages: tuple[ThrusterOutage, ...] = ()
    motions: tuple[ObstacleMotion, ...] = ()
    cache_dir: Path | None = None
    gains: PidGains | None = None
    load: EnvironmentalLoad | None = None
    synthesis_latency_s: float = 0.0
    select: str = "J"
    pose_noise_scale: float = 1.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.pose_noise_scale) and self.pose_noise_scale > 0.0):
            raise ValueError(f"pose_noise_scale must be > 0, got {self.pose_noise_scale!r}")


def world_motions(scenario: Scenario, spec: SimRunSpec) -> tuple[ObstacleMotion, ...]:
    """Return every obstacle motion of the run's simulated world.

    The scenario's ``[[simulated_motion]]`` first, then the spec's own motions (fault
    injection, as ``hil record-suite`` schedules; not held to the speed bound), all
    scheduled together: motions of one obstacle add up
    (:func:`~hil.core.motion.displacements_m`).
    """
    return scenario.simulation.motions + spec.motions




class RecordingSolver:
    """A layout solver that remembers which controller each synthesis version returned.

    The resynthesizer numbers its syntheses 1, 2, ... in call order, failures included;
    this counts the same way. Every call synthesizes (a re-synthesis timer must cost what
    it costs on the vessel). :attr:`controllers` gives each version's controller: a few
    are kept in memory (:class:`ControllerLru`; a paper-grid controller holds about 300
    MB and a moving obstacle brings a new layout every report), the others solved again
    on demand, a read from the solved-controller store.

    Args:
        solver: The solver to wrap.
    """

    def __init__(self, solver: LayoutSolver) -> None:
        self._solver = solver
        self._calls = 0
        self._kept: ControllerLru[SymbolicAdapter] = ControllerLru()
        self._asked: dict[int, tuple[ObstacleLayout, float]] = {}
        self.controllers = VersionControllers(self)

    def __call__(self, layout: ObstacleLayout, report_age_s: float) -> SymbolicAdapter:
        """Solve `layout` for `report_age_s` and remember it under its version."""
        self._calls += 1
        solved = self._solver(layout, report_age_s)
        self._asked[self._calls] = (layout, report_age_s)
        key = (layout.obstacles, report_age_s)
        if self._kept.get(key) is None:
            self._kept.put(key, solved, solved.controller)
        return solved

    def versions(self) -> list[int]:
        """Return the synthesis versions that returned a controller, in order."""
        return sorted(self._asked)

    def controller_of(self, version: int) -> Controller:
        """Return the controller of synthesis `version` (solved again if not kept).

        Raises:
            KeyError: No synthesis of that version returned a controller.
        """
        layout, age = self._asked[version]
        key = (layout.obstacles, age)
        adapter = self._kept.get(key)
        if adapter is None:
            adapter = self._solver(layout, age)
            self._kept.put(key, adapter, adapter.controller)
        return adapter.controller


class VersionControllers(Mapping[int, Controller]):
    """The controllers of a run by synthesis version, read through a :class:`RecordingSolver`."""

    def __init__(self, solver: RecordingSolver) -> None:
        self._solver = solver

    def __getitem__(self, version: int) -> Controller:
        return self._solver.controller_of(version)

    def __iter__(self) -> Iterator[int]:
        return iter(self._solver.versions())

    def __len__(self) -> int:
        return len(self._solver.versions())


def sim_config(spec: SimRunSpec, scenario: Scenario) -> SimConfig:
    """Return the simulated world of a run: start, seed, faults, load and obstacles.

    The obstacles are the scenario's (their bounding boxes, as the tracker reports them),
    moved by :func:`world_motions` and reported every ``[sim] obstacle_report_period_s``.
    """
    start = spec.start if spec.start is not None else default_start(scenario)
    return SimConfig(
        start=start,
        start_velocity=(0.0, 0.0, 0.0) if spec.start_velocity is None else spec.start_velocity,
        seed=spec.seed,
        obstacles=layout_from_scenario(scenario).obstacles,
        motions=world_motions(scenario, spec),
        obstacle_report_period_s=scenario.simulation.obstacle_report_period_s,
        pose=_pose_sensor(spec),
        thruster_outages=spec.thruster_outages,
        loop_stalls_s=spec.loop_stalls_s,
        load=spec.load if spec.load is not None else EnvironmentalLoad(),
    )


def _pose_sensor(spec: SimRunSpec) -> PoseSensorConfig:
    default = PoseSensorConfig()
    k = spec.pose_noise_scale
    return replace(
        default, scheduled_dropouts_s=spec.pose_outages_s,
        noise_std_x_m=k * default.noise_std_x_m, noise_std_y_m=k * default.noise_std_y_m,
        noise_std_yaw_rad=k * default.noise_std_yaw_rad,
    )  # fmt: skip


LiveView = Callable[[Scenario, RunLog], RunLog]
"""Wraps a run's log to show it live (e.g. a Rerun stream) and passes every call on."""


@dataclass(frozen=True, eq=False)
class SimOutcome:
    """A finished simulated run with what a judge of its true state needs.

    Attributes:
        summary: The run's summary.
        scenario: The scenario it ran.
        sim: The simulated world (its :meth:`SimWorld.truth` is the true trajectory).
        stats: What the loop counted.
        controllers: Every controller the run synthesized, by synthesis version (the
            ``controller_version`` of its decisions).
    """

    summary: RunSummary
    scenario: Scenario
    sim: SimWorld
    stats: RunStats
    controllers: Mapping[int, Controller]


def run_in_sim(
    spec: SimRunSpec, log: RunLog | None = None, live: LiveView | None = None, *,
    handle_signals: bool = False,
) -> RunSummary:
    """Run one docking in simulation and summarize it (see module docstring).

    Args:
        spec: The run.
        log: Where to record when `spec.out_dir` is None (default: a fresh MemoryLog).
        live: Wraps the log for a live view (the views layer provides Rerun's); None
            shows nothing.
        handle_signals: Route SIGINT/SIGTERM to a clean stop at the next tick (the run
            then ends "stopped by SIGINT" with a complete log) instead of an exception.
    """
    return simulate(spec, log, live, handle_signals=handle_signals).summary


def simulate(
    spec: SimRunSpec, log: RunLog | None = None, live: LiveView | None = None,
    select: Select | None = None, *, handle_signals: bool = False,
) -> SimOutcome:
    """Run one docking in simulation; return its summary, world and controllers.

    Args:
        spec: The run.
        log: Where to record when `spec.out_dir` is None (default: a fresh MemoryLog).
        live: Wraps the log for a live view; None shows nothing.
        select: Choice among the safe inputs (tests force choices with it); None: the
            spec's policy (:mod:`hil.runs.policies`; the paper's J by default).
        handle_signals: Route SIGINT/SIGTERM to a clean stop at the next tick.
    """
    wall_start = time.perf_counter()
    scenario = load_scenario(spec.scenario)
    wait_select: Select = wait_slowest
    if select is None:
        steps = np.array([scenario.surge.step, scenario.sway.step, scenario.yaw_rate.step])
        select = policy(spec.select, spec.seed, steps, scenario)
        if spec.select != "J":  # an adversary picks among the staying inputs too
            wait_select = select
    config = sim_config(spec, scenario)
    start = config.start
    sim = SimWorld(config, max_duration_s=spec.loop.max_duration_s + 10.0)
    world = World(sim.clock, sim.pose, sim.imu, sim.obstacles, sim.thrusters)
    synthesizer = synthesizer_for(scenario, spec.cache_dir, spec.loop.synthesis_threads)
    sources_before = synthesizer.sources.copy()
    recorder: Recorder | None = None
    if spec.out_dir is not None:
        # The full specification goes into the metadata, so a replay re-simulates exactly.
        run_spec = json.dumps(spec_to_json(replace(spec, start=start)))
        recorder = Recorder(spec.out_dir, RunInfo.current(spec.scenario, scenario_hash(scenario),
                                                          spec.seed, backend="sim",
                                                          run_spec=run_spec))
        recorder.open()
        log = recorder
    elif log is None:
        log = MemoryLog()
    if live is not None:
        log = live(scenario, log)
    solver = RecordingSolver(LayoutSolver(scenario, synthesizer))
    try:
        runtime = build_runtime(
            scenario, world, log, spec.loop, synthesizer, ResynthesisMode.INLINE,
            select=select, wait_select=wait_select, solver=solver, gains=spec.gains,
            synthesis_latency_s=spec.synthesis_latency_s,
            start_nu=None if spec.start_velocity is None else np.array(spec.start_velocity))
        signals = stop_on_signals(runtime.request_stop) if handle_signals else nullcontext()
        with signals:
            stats = runtime.run()
    finally:
        if recorder is not None:
            recorder.close()
    summary = summarize(spec, scenario, sim, stats, time.perf_counter() - wall_start,
                        synthesizer.sources.minus(sources_before))
    return SimOutcome(summary, scenario, sim, stats, solver.controllers)


def summarize(spec: SimRunSpec, scenario: Scenario, sim: SimWorld, stats: RunStats,
              wall_s: float, sources: ControllerSources | None = None) -> RunSummary:
    """Judge a finished simulated run by the world's ground truth.

    `sources` says where its controllers came from (solved, store, memory); None: not counted.
    """
    truth = sim.truth()
    offsets = displacements_m(sim.config.motions, len(sim.config.obstacles), truth[:, 0])
    rows = np.minimum(np.asarray(stats.t_ns, dtype=np.int64) // round(sim.config.dt_s * NS_PER_S),
                      max(len(truth) - 1, 0))
    return summarize_run(
        scenario=scenario, scenario_name=spec.scenario, seed=spec.seed,
        backend="sim", stats=stats, trajectory=truth[:, 1 + TR_ETA : 1 + TR_ETA + 3],
        velocity=truth[rows, 1 + TR_NU : 1 + TR_NU + 3].reshape(-1, 3), wall_s=wall_s,
        log=None if spec.out_dir is None else str(spec.out_dir),
        nominal_s=1.0 / spec.loop.loop_hz,
        obstacle_offsets_m=offsets if sim.config.motions else None, sources=sources)


def spec_to_json(spec: SimRunSpec) -> dict[str, Any]:
    """Return the parts of a run specification a suite manifest keeps.

    A start at rest writes no ``start_velocity`` (nor shipped gains ``gains``, nor calm
    water ``load``), so specs recorded before they existed read back unchanged.
    """
    moving = {} if spec.start_velocity is None else {"start_velocity": list(spec.start_velocity)}
    return {
        "scenario": spec.scenario,
        "seed": spec.seed,
        "start": None if spec.start is None else list(spec.start),
        **moving,
        "pose_outages_s": [list(p) for p in spec.pose_outages_s],
        **({"loop_stalls_s": [list(p) for p in spec.loop_stalls_s]} if spec.loop_stalls_s else {}),
        "thruster_outages": [[o.start_s, o.stop_s] for o in spec.thruster_outages],
        "motions": [
            {
                "index": m.index,
                "velocity_mps": list(m.velocity_mps),
                "start_s": m.start_s,
                "stop_s": m.stop_s,
            }
            for m in spec.motions
        ],
        "max_duration_s": spec.loop.max_duration_s,
        **({} if spec.gains is None else {"gains": to_jsonable(spec.gains)}),
        **({} if spec.load is None else {"load": to_jsonable(spec.load)}),
        **({"synthesis_latency_s": spec.synthesis_latency_s} if spec.synthesis_latency_s else {}),
        **({"select": spec.select} if spec.select != "J" else {}),
        **({"pose_noise_scale": spec.pose_noise_scale} if spec.pose_noise_scale != 1.0 else {}),
    }


def spec_from_json(data: dict[str, Any]) -> SimRunSpec:
    """Rebuild a run specification from :func:`spec_to_json`'s form.

    Raises:
        ValueError: A field is missing or malformed.
    """
    try:
        start = data.get("start")
        nu = data.get("start_velocity")
        return SimRunSpec(
            scenario=str(data["scenario"]),
            seed=int(data["seed"]),
            start=None if start is None else (float(start[0]), float(start[1]), float(start[2])),
            start_velocity=None if nu is None else (float(nu[0]), float(nu[1]), float(nu[2])),
            loop=LoopConfig(max_duration_s=float(data.get("max_duration_s", 600.0))),
            pose_outages_s=tuple((float(a), float(b)) for a, b in data.get("pose_outages_s", [])),
            loop_stalls_s=tuple((float(a), float(b)) for a, b in data.get("loop_stalls_s", [])),
            thruster_outages=tuple(
                ThrusterOutage(float(a), float(b)) for a, b in data.get("thruster_outages", [])
            ),
            motions=tuple(
                ObstacleMotion(
                    int(m["index"]),
                    (float(m["velocity_mps"][0]), float(m["velocity_mps"][1])),
                    float(m["start_s"]),
                    float(m["stop_s"]),
                )
                for m in data.get("motions", [])
            ),
            gains=None if data.get("gains") is None else from_jsonable(PidGains, data["gains"]),
            load=None if data.get("load") is None
            else from_jsonable(EnvironmentalLoad, data["load"]),
            synthesis_latency_s=float(data.get("synthesis_latency_s", 0.0)),
            select=str(data.get("select", "J")),
            pose_noise_scale=float(data.get("pose_noise_scale", 1.0)),
        )
    except (KeyError, TypeError, IndexError) as err:
        raise ValueError(f"malformed run specification {data!r}: {err!r}") from err
