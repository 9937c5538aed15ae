"""Monte Carlo campaigns: many simulated dockings from random starts, in parallel.

Each run is :func:`hil.runs.guarantee.judged_run` on a picklable
:class:`~hil.runs.sim_run.SimRunSpec` (the run, and its guarantee violations on
the true state), so any executor that maps a function over specs (local
processes or a Dask cluster: :mod:`hil.runs.executor`, :mod:`hil.runs.fanout`) can
run a campaign, streaming each finished run to a results file. A share of the starts may be moving:
their initial body velocity is drawn uniformly in the scenario's input box.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from hil.adapters.sim import SimConfig, SimWorld
from hil.controllers.symbolic import Controller
from hil.core.arrays import FloatArray
from hil.core.codec import from_jsonable, to_jsonable
from hil.runs.clearance import hull_margin_series
from hil.runs.executor import Executor, LocalExecutor
from hil.runs.fanout import Failure, Job, Report, fan_out
from hil.runs.guarantee import GuaranteeViolations, judged_run
from hil.runs.results import ResultStream
from hil.runs.sim_run import SimRunSpec
from hil.runs.summary import RunSummary
from hil.runtime.assembly import low_level_for
from hil.runtime.settings import NS_PER_S, LoopConfig
from hil.scenarios import Scenario
from hil.sim.plant import P_ETA, P_NU, TR_ETA

PAPER_TANK_MINUTES = (2.67, 1.71, 3.66)
"""Docking time in the towing tank (paper): mean, min, max (min)."""


Velocity = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class StartRegion:
    """Where random starts are drawn: a box in (x, y) and any heading.

    The default is the paper's: right of O1 (x > 2.75 m), clear of the walls;
    :meth:`of` gives the same kind of box for any scenario.
    """

    x_m: tuple[float, float] = (3.0, 4.0)
    y_m: tuple[float, float] = (-2.4, 2.4)

    @staticmethod
    def of(scenario: Scenario) -> StartRegion:
        """Return the box 0.5 to 1.5 m left of the right wall, 0.6 m clear of the others."""
        x1 = scenario.x_range_m[1]
        y0, y1 = scenario.y_range_m
        return StartRegion((x1 - 1.5, x1 - 0.5), (y0 + 0.6, y1 - 0.6))


def draw_starts(controller: Controller, n: int, seed: int,
                region: StartRegion | None = None,
                velocities: Sequence[Velocity | None] | None = None,
                settle_s: float = 0.0,
                scenario: Scenario | None = None,
                ) -> tuple[list[tuple[float, float, float]], int]:
    """Draw `n` start poses in the region that the controller calls winning.

    With `scenario`, a start whose hull is not clear of the walls and the real
    obstacles at every physics step until that first decision is discarded too: the
    guarantee begins at the first decision, and a pose drawn 0.5 m from a wall may
    already put a hull corner past it.

    Winning as the runtime's first decision sees it: some input is safe with the input
    nearest the vessel's velocity in force, every candidate budgeted as a first command
    (:meth:`Controller.decision_value`), at the state the vessel is in when that
    decision is taken: `settle_s` after the start (:func:`first_decision_state`: it
    drifts with idle thrusters while the observer settles). `velocities[i]` (m/s, m/s,
    rad/s; None: at rest) is run i's start velocity.

    Returns:
        The starts and how many draws were discarded as not winning.
    """
    region = region or StartRegion()
    rng = np.random.default_rng(seed)
    starts: list[tuple[float, float, float]] = []
    discarded = 0
    while len(starts) < n:
        pose = (float(rng.uniform(*region.x_m)), float(rng.uniform(*region.y_m)),
                float(rng.uniform(-math.pi, math.pi)))
        velocity = None if velocities is None else velocities[len(starts)]
        path, nu = first_decision_path(pose, velocity, settle_s)
        at = (float(path[-1, 0]), float(path[-1, 1]), float(path[-1, 2]))
        reference = None if nu is None else controller.lattice.nearest(np.array(nu))
        clear = scenario is None or bool(np.all(hull_margin_series(scenario, path) > 0.0))
        if clear and math.isfinite(controller.decision_value(at, reference, first=True)):
            starts.append(pose)
        else:
            discarded += 1
            if discarded > 100 * n:
                raise ValueError(f"the start region {region!r} holds almost no winning state")
    return starts, discarded








def first_decision_state(
    pose: tuple[float, float, float], velocity: Velocity | None, settle_s: float,
    loop_hz: float = 20.0,
) -> tuple[tuple[float, float, float], Velocity | None]:
    """Return the (pose, velocity) a run started there is predicted in at `settle_s`.

    Until the observer has settled (``LoopConfig.observer_settle_s``, and the tick
    that decides) the runtime flies velocity zero under the low level, from its first
    estimate (the tick after the first pose) on: a vessel started moving brakes, and
    its first decision is taken where it got to, from the input nearest its velocity
    then. Predicted with the runtime's low level at `loop_hz` on the simulated plant in
    calm water, fed the true velocity where the runtime feeds its estimate (measured
    against full runs: within 1 cm and 0.01 rad at 1.05 s, what the estimate's error
    makes of the braking); a start at rest stays put.
    """
    path, nu = first_decision_path(pose, velocity, settle_s, loop_hz)
    x, y, psi = (float(a) for a in path[-1])
    return (x, y, psi), nu


def first_decision_path(
    pose: tuple[float, float, float], velocity: Velocity | None, settle_s: float,
    loop_hz: float = 20.0,
) -> tuple[FloatArray, Velocity | None]:
    """Return the poses a run started there is predicted to pass until `settle_s`.

    As :func:`first_decision_state` predicts them, at every physics step.

    Returns:
        The poses (x m, y m, psi rad), shape (N, 3), the start first and the pose at
        `settle_s` last (one row for a start at rest), and the velocity then.
    """
    if velocity is None or settle_s <= 0.0:
        return np.array([pose], dtype=np.float64), velocity
    sim = SimWorld(SimConfig(start=pose, start_velocity=velocity), max_duration_s=settle_s + 1.0)
    low_level = low_level_for(loop_hz)
    period_ns = round(NS_PER_S / loop_hz)
    end_ns = round(settle_s * NS_PER_S)
    t_ns = period_ns  # the first tick with an estimate: the first pose arrives after t = 0
    while t_ns < end_ns:
        sim.clock.sleep_until(t_ns)
        nu = sim.state[P_NU : P_NU + 3].copy()
        sim.thrusters.send(low_level.step(np.zeros(3), nu, t_ns).command)
        t_ns += period_ns
    sim.clock.sleep_until(end_ns)
    u, v, r = (float(a) for a in sim.state[P_NU : P_NU + 3])
    path = np.vstack([np.array(pose, dtype=np.float64), sim.truth()[:, 1 + TR_ETA : 4 + TR_ETA],
                      sim.state[P_ETA : P_ETA + 3]])
    return path, (u, v, r)


def first_decision_s(loop: LoopConfig) -> float:
    """Return when a run's first decision is taken (s after the start).

    The observer's settling time and the tick that decides: 1.05 s with the defaults.
    """
    return loop.observer_settle_s + 1.0 / loop.loop_hz


def draw_velocities(scenario: Scenario, n: int, moving: float, seed: int) -> list[Velocity | None]:
    """Draw `n` start velocities: a share `moving` uniform in the input box, the rest at rest.

    The box is the scenario's surge x sway x yaw-rate input ranges (m/s, m/s, rad/s).
    Which runs move is drawn too (each with probability `moving`). The stream is
    separate from :func:`draw_starts`' for the same seed, so the starts do not change.

    Raises:
        ValueError: `moving` is outside [0, 1].
    """
    if not 0.0 <= moving <= 1.0:
        raise ValueError(f"the moving share must lie in [0, 1], got {moving!r}")
    rng = np.random.default_rng([seed, 1])
    lo = np.array([scenario.surge.min, scenario.sway.min, scenario.yaw_rate.min])
    hi = np.array([scenario.surge.max, scenario.sway.max, scenario.yaw_rate.max])
    out: list[Velocity | None] = []
    for _ in range(n):
        is_moving = rng.random() < moving
        nu = rng.uniform(lo, hi)
        out.append((float(nu[0]), float(nu[1]), float(nu[2])) if is_moving else None)
    return out


def campaign_specs(base: SimRunSpec, starts: Iterable[tuple[float, float, float]],
                   seed0: int = 0,
                   velocities: Iterable[Velocity | None] | None = None) -> list[SimRunSpec]:
    """Return one spec per start, seeds counting up from `seed0`, nothing recorded.

    `velocities` gives each start's initial body velocity (None: at rest); all at
    rest if omitted.
    """
    starts = list(starts)
    nus = [None] * len(starts) if velocities is None else list(velocities)
    if len(nus) != len(starts):
        raise ValueError(f"{len(nus)} velocities for {len(starts)} starts")
    return [replace(base, seed=seed0 + i, start=start, start_velocity=nu, out_dir=None)
            for i, (start, nu) in enumerate(zip(starts, nus, strict=True))]


CampaignRun = tuple[RunSummary, GuaranteeViolations]
"""One run of a campaign: its summary and its guarantee violations on the true state."""


def warm_sim(scenarios: tuple[str, ...]) -> None:
    """Warm a worker for simulated runs: one short judged run per scenario.

    It loads (or compiles, once, under the cache lock) every numba kernel a run
    uses and reads the scenario's abstraction tables, so the worker's first real run
    costs what the others do.
    """
    for scenario in scenarios:
        judged_run(SimRunSpec(scenario=scenario, loop=LoopConfig(
            resynthesis_period_s=None, max_duration_s=2.0)))


def _decode_run(data: object) -> CampaignRun:
    summary, violations = from_jsonable(CampaignRun, data)
    return summary, violations


def sim_job(name: str, scenarios: Iterable[str]) -> Job[SimRunSpec, CampaignRun]:
    """Return the job of a campaign or sweep: judged simulated runs of `scenarios`.

    Args:
        name: "campaign" or "sweep" (names the results file's plan).
        scenarios: The scenarios its runs use (each worker warms on them).
    """
    return Job(name, judged_run, to_jsonable, to_jsonable, _decode_run,
               partial(warm_sim, tuple(sorted(set(scenarios)))))


@dataclass(frozen=True, slots=True)
class CampaignResult:
    """The finished runs of a campaign, complete or stopped.

    Attributes:
        runs: Each finished run, in spec order.
        specs: The spec of each finished run, same order.
        planned: How many runs were asked for.
        failures: The runs that raised, each with its spec (JSON-ready) and why.
        reason: Why the campaign stopped early ("" when every run was tried).
        resumed: Runs read back from the results file.
        retried: Runs started again because their worker died.
    """

    runs: list[CampaignRun]
    specs: list[SimRunSpec]
    planned: int
    failures: tuple[Failure, ...] = ()
    reason: str = ""
    resumed: int = 0
    retried: int = 0

    @property
    def stopped(self) -> bool:
        """Whether the campaign was stopped before every run was tried."""
        return bool(self.reason)


def run_campaign(specs: list[SimRunSpec], executor: Executor | int,
                 progress: Callable[[CampaignRun], None] | None = None, *,
                 stream: ResultStream | None = None,
                 job: Job[SimRunSpec, CampaignRun] | None = None,
                 report: Report | None = None) -> CampaignResult:
    """Run and judge every spec on `executor` (or on that many local processes).

    Ctrl-C (KeyboardInterrupt) stops the campaign without losing what it did: no new run
    starts, the runs already going finish, and the result holds every finished run (a
    second Ctrl-C while they finish gives up on them). See :func:`hil.runs.fanout.fan_out`.

    Args:
        specs: The runs.
        executor: Where to run them; an int opens that many local processes.
        progress: Called with each finished run, in this process.
        stream: The results file (opened); its runs are read back, not run again.
        job: The job (default: :func:`sim_job` of the specs' scenarios).
        report: Called with every run that ends, finished or failed (a progress bar).
    """
    job = job or sim_job("campaign", (s.scenario for s in specs))

    def ended(index: int, outcome: object) -> None:
        if report is not None:
            report(index, outcome)
        if progress is not None and not isinstance(outcome, Failure):
            progress(outcome)  # type: ignore[arg-type]

    if isinstance(executor, int):
        with LocalExecutor(executor, job.warm) as local:
            out = fan_out(job, specs, local, stream, ended)
    else:
        out = fan_out(job, specs, executor, stream, ended)
    finished = [(spec, r) for spec, r in zip(specs, out.results, strict=True) if r is not None]
    return CampaignResult([r for _, r in finished], [spec for spec, _ in finished], len(specs),
                          tuple(out.failures), out.stopped, out.resumed, out.retried)


@dataclass(frozen=True, slots=True)
class CampaignStats:
    """What a campaign achieved.

    Attributes:
        runs: Number of runs.
        docked: Runs that docked.
        contacts: Runs with any hull contact with a real obstacle.
        docking_min: Docking times of the docked runs: mean, min, max (min).
        min_clearance_m: Least hull clearance over all runs (m).
        tracking_rms: Mean over runs of the per-axis RMS tracking error
            (m/s, m/s, deg/s).
        wall_s_mean: Mean wall time per run (s).
        lost_at_start: Runs whose first decision found no safe input although the draw
            judged the state the vessel drifts to by then winning (the estimate in
            another cell than the truth); the guarantee speaks of the others only.
        moving_obstacle_runs: Runs in which some obstacle moved (the simulated world's
            scheduled motions).
        resyntheses: Controllers synthesized and swapped in, over all runs.
        stale_stops: Stops for an obstacle report too old to decide on, over all runs.
    """

    runs: int
    docked: int
    contacts: int
    docking_min: tuple[float, float, float]
    min_clearance_m: float
    tracking_rms: tuple[float, float, float]
    wall_s_mean: float
    lost_at_start: int = 0
    moving_obstacle_runs: int = 0
    resyntheses: int = 0
    stale_stops: int = 0

    @property
    def winning_starts(self) -> int:
        """Return the runs whose first decision found a safe input."""
        return self.runs - self.lost_at_start

    @staticmethod
    def of(summaries: list[RunSummary]) -> CampaignStats:
        """Aggregate run summaries."""
        times = np.array([s.docking_time_s for s in summaries
                          if s.docked and s.docking_time_s is not None]) / 60.0
        rms = np.array([s.tracking.rms for s in summaries]).reshape(-1, 3)
        return CampaignStats(
            runs=len(summaries),
            docked=sum(s.docked for s in summaries),
            contacts=sum(s.hull_contacts > 0 for s in summaries),
            docking_min=(float(times.mean()), float(times.min()), float(times.max()))
            if len(times) else (math.nan, math.nan, math.nan),
            min_clearance_m=min((s.min_clearance_m for s in summaries), default=math.inf),
            tracking_rms=tuple(float(v) for v in np.nanmean(rms, axis=0))  # type: ignore[arg-type]
            if len(rms) else (math.nan, math.nan, math.nan),
            wall_s_mean=float(np.mean([s.wall_s for s in summaries])) if summaries else math.nan,
            lost_at_start=sum(
                s.aborted and s.decisions <= 1 and s.not_winning_decisions >= 1 for s in summaries
            ),
            moving_obstacle_runs=sum(s.moving_obstacles > 0 for s in summaries),
            resyntheses=sum(s.resyntheses for s in summaries),
            stale_stops=sum(s.obstacle_stale_stops for s in summaries),
        )
