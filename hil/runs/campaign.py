"""Monte Carlo campaigns: many simulated dockings from random starts, in parallel.

Each run is :func:`hil.runs.sim_run.run_in_sim` on a picklable
:class:`~hil.runs.sim_run.SimRunSpec`, so any executor that maps a function
over specs (processes here; a cluster later) can run a campaign.
"""

from __future__ import annotations

import math
import multiprocessing
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic import Controller
from hil.runs.sim_run import SimRunSpec, run_in_sim
from hil.runs.summary import RunSummary

FloatArray = NDArray[np.float64]

PAPER_TANK_MINUTES = (2.67, 1.71, 3.66)
"""Docking time in the towing tank (paper): mean, min, max (min)."""


@dataclass(frozen=True, slots=True)
class StartRegion:
    """Where random starts are drawn: a box in (x, y) and any heading.

    The default is the paper's: right of O1 (x > 2.75 m), clear of the walls.
    """

    x_m: tuple[float, float] = (3.0, 4.0)
    y_m: tuple[float, float] = (-2.4, 2.4)


def draw_starts(controller: Controller, n: int, seed: int,
                region: StartRegion | None = None) -> tuple[list[tuple[float, float, float]], int]:
    """Draw `n` start poses in the region that lie in the winning set.

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
        if controller.is_winning(pose):
            starts.append(pose)
        else:
            discarded += 1
            if discarded > 100 * n:
                raise ValueError(f"the start region {region!r} holds almost no winning state")
    return starts, discarded


def campaign_specs(base: SimRunSpec, starts: Iterable[tuple[float, float, float]],
                   seed0: int = 0) -> list[SimRunSpec]:
    """Return one spec per start, seeds counting up from `seed0`, nothing recorded."""
    return [replace(base, seed=seed0 + i, start=start, out_dir=None)
            for i, start in enumerate(starts)]


def run_campaign(specs: list[SimRunSpec], workers: int,
                 progress: Callable[[RunSummary], None] | None = None) -> list[RunSummary]:
    """Run every spec, `workers` processes at a time; summaries in spec order."""
    results: list[RunSummary | None] = [None] * len(specs)
    if workers <= 1:
        for i, spec in enumerate(specs):
            results[i] = run_in_sim(spec)
            if progress is not None:
                progress(results[i])  # type: ignore[arg-type]
    else:
        # Spawn, not fork: the parent has run numba's threaded kernels, and a forked
        # child of a threaded process may crash in the threading layer.
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
            futures = {pool.submit(run_in_sim, spec): i for i, spec in enumerate(specs)}
            for future in as_completed(futures):
                summary = future.result()
                results[futures[future]] = summary
                if progress is not None:
                    progress(summary)
    return [r for r in results if r is not None]


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
    """

    runs: int
    docked: int
    contacts: int
    docking_min: tuple[float, float, float]
    min_clearance_m: float
    tracking_rms: tuple[float, float, float]
    wall_s_mean: float

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
        )
