"""Monte Carlo campaigns: many simulated dockings from random starts, in parallel.

Each run is :func:`hil.runs.guarantee.judged_run` on a picklable
:class:`~hil.runs.sim_run.SimRunSpec` (the run, and its guarantee violations on
the true state), so any executor that maps a function over specs (processes
here; a cluster later) can run a campaign. A share of the starts may be moving:
their initial body velocity is drawn uniformly in the scenario's input box.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import signal
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic import Controller
from hil.runs.guarantee import GuaranteeViolations, judged_run
from hil.runs.sim_run import SimRunSpec
from hil.runs.summary import RunSummary
from hil.scenarios import Scenario

FloatArray = NDArray[np.float64]

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
                ) -> tuple[list[tuple[float, float, float]], int]:
    """Draw `n` start poses in the region that the controller calls winning.

    Winning as the runtime's first decision sees it: some input is safe with the input
    nearest the start velocity in force, every candidate budgeted as a first command
    (:meth:`Controller.decision_value`); `velocities[i]` (m/s, m/s, rad/s; None: at
    rest) is run i's start velocity.

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
        reference = None if velocity is None else controller.lattice.nearest(np.array(velocity))
        if math.isfinite(controller.decision_value(pose, reference, first=True)):
            starts.append(pose)
        else:
            discarded += 1
            if discarded > 100 * n:
                raise ValueError(f"the start region {region!r} holds almost no winning state")
    return starts, discarded




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


@dataclass(frozen=True, slots=True)
class CampaignResult:
    """The finished runs of a campaign, complete or stopped.

    Attributes:
        runs: Each finished run, in spec order.
        specs: The spec of each finished run, same order.
        planned: How many runs were asked for.
    """

    runs: list[CampaignRun]
    specs: list[SimRunSpec]
    planned: int

    @property
    def stopped(self) -> bool:
        """Whether the campaign was stopped before every run finished."""
        return len(self.runs) < self.planned


def _ignore_sigint() -> None:
    """Worker initializer: Ctrl-C is the parent's to handle (it lets running runs finish)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def run_campaign(specs: list[SimRunSpec], workers: int,
                 progress: Callable[[CampaignRun], None] | None = None) -> CampaignResult:
    """Run and judge every spec, `workers` processes at a time.

    Ctrl-C (KeyboardInterrupt) stops the campaign without losing what it did: no new run
    starts, the runs already going finish, and the result holds every finished run (a
    second Ctrl-C while they finish gives up on them).
    """
    results: list[CampaignRun | None] = [None] * len(specs)
    if workers <= 1:
        with contextlib.suppress(KeyboardInterrupt):
            for i, spec in enumerate(specs):
                results[i] = judged_run(spec)
                if progress is not None:
                    progress(results[i])  # type: ignore[arg-type]
    else:
        # Spawn, not fork: the parent has run numba's threaded kernels, and a forked
        # child of a threaded process may crash in the threading layer.
        context = multiprocessing.get_context("spawn")
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=context,
                                   initializer=_ignore_sigint)
        futures = {pool.submit(judged_run, spec): i for i, spec in enumerate(specs)}
        try:
            for future in as_completed(futures):
                result = future.result()
                results[futures[future]] = result
                if progress is not None:
                    progress(result)
        except KeyboardInterrupt:
            pass  # no new run starts; the shutdown below lets the running ones finish
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
        for future, i in futures.items():
            if results[i] is None and future.done() and not future.cancelled() \
                    and future.exception() is None:
                results[i] = future.result()
    finished = [(spec, r) for spec, r in zip(specs, results, strict=True) if r is not None]
    return CampaignResult([r for _, r in finished], [spec for spec, _ in finished], len(specs))


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
        lost_at_start: Runs whose first decision found no safe input (the start the
            campaign drew was winning, but the vessel drifted while the observer settled
            before the first decision); the guarantee speaks of the others only.
    """

    runs: int
    docked: int
    contacts: int
    docking_min: tuple[float, float, float]
    min_clearance_m: float
    tracking_rms: tuple[float, float, float]
    wall_s_mean: float
    lost_at_start: int = 0

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
        )
