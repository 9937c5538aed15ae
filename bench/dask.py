"""Benchmark: a campaign on Dask against the plain local pool, and a worker killed mid-campaign.

The same campaign (random winning starts of the scenario, half moving) runs on

- the plain local pool (:class:`~hil.runs.executor.LocalExecutor`, N spawned processes),
- a local Dask cluster of one worker, and of N workers (one thread each),

each warmed first (numba and the controller in every worker), then timed in
interleaved rounds (best of each, as the machine's other load varies). A last run
on the N-worker cluster kills one worker process a third of the way through. Printed
as ratios measured in this one run:

- scaling: Dask with N workers against one, goal >= 1.8x for N = 2;
- overhead: Dask with N workers against the local pool of N processes, goal <= 5 %;
- lost runs with a worker killed: goal 0 (finished + failed = planned, none failed).

    python -m bench dask [--runs 200] [--workers 2] [--rounds 2] [--scenario coarse]
                         [--max-duration 60]
"""

from __future__ import annotations

import argparse
import os
import signal
import time
from dataclasses import replace

from hil.runs.campaign import (
    CampaignRun,
    StartRegion,
    campaign_specs,
    draw_starts,
    draw_velocities,
    sim_job,
)
from hil.runs.dask_executor import DaskExecutor
from hil.runs.executor import Executor, LocalExecutor
from hil.runs.fanout import FanOut, fan_out
from hil.runs.sim_run import SimRunSpec
from hil.runs.stack_assembly import synthesizer_for
from hil.runtime.assembly import LayoutSolver, layout_from_scenario
from hil.runtime.settings import LoopConfig
from hil.scenarios import load_scenario


def _specs(scenario_name: str, n: int, max_duration_s: float) -> list[SimRunSpec]:
    scenario = load_scenario(scenario_name)
    controller = LayoutSolver(scenario, synthesizer_for(scenario))(
        layout_from_scenario(scenario)).controller
    velocities = draw_velocities(scenario, n, 0.5, seed=0)
    starts, _ = draw_starts(controller, n, 0, StartRegion.of(scenario), velocities,
                            scenario=scenario)
    base = SimRunSpec(scenario=scenario_name, loop=LoopConfig(
        resynthesis_period_s=None, max_duration_s=max_duration_s))
    return campaign_specs(base, starts, velocities=velocities)


def _warm(executor: Executor, warm_specs: list[SimRunSpec]) -> None:
    """Warm every worker (numba, its controller): short runs until each has had some."""
    fan_out(sim_job("campaign", {s.scenario for s in warm_specs}), warm_specs, executor)


def _time(executor: Executor, specs: list[SimRunSpec]) -> tuple[float, FanOut[CampaignRun]]:
    start = time.perf_counter()
    out = fan_out(sim_job("campaign", {s.scenario for s in specs}), specs, executor)
    return time.perf_counter() - start, out


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print its ratios."""
    parser = argparse.ArgumentParser(prog="python -m bench dask", description=__doc__)
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--scenario", default="coarse")
    parser.add_argument("--max-duration", type=float, default=60.0)
    parser.add_argument("--rounds", type=int, default=2,
                        help="timed rounds per executor, interleaved; the best counts")
    args = parser.parse_args(argv)
    n = args.workers
    specs = _specs(args.scenario, args.runs, args.max_duration)
    # Short runs, four per worker, so that every worker process has warmed before timing.
    warm_specs = [replace(s, loop=replace(s.loop, max_duration_s=2.0)) for s in specs[:4 * n]]
    job = sim_job("campaign", [args.scenario])
    job.warm()  # this process too (it fills the cache the workers load)
    rows: dict[str, tuple[float, FanOut[CampaignRun]]] = {}
    labels = (f"local pool, {n} processes", "Dask, 1 worker", f"Dask, {n} workers")
    with LocalExecutor(n) as pool, DaskExecutor(None, 1) as one, DaskExecutor(None, n) as many:
        many.wait_for_workers(n)
        executors: tuple[Executor, ...] = (pool, one, many)
        for executor in executors:
            _warm(executor, warm_specs)
        # Interleaved rounds, best of each: the machine's other load comes and goes.
        for _ in range(args.rounds):
            for label, executor in zip(labels, executors, strict=True):
                wall, out = _time(executor, specs)
                if label not in rows or wall < rows[label][0]:
                    rows[label] = (wall, out)
        # A worker killed a third of the way: its nanny restarts it, Dask reruns its runs.
        pids = list(many.client.run(os.getpid).values())
        ended: list[int] = []

        def kill_one(index: int, _outcome: object) -> None:
            ended.append(index)
            if len(ended) == len(specs) // 3:
                os.kill(pids[0], signal.SIGKILL)

        start = time.perf_counter()
        killed = fan_out(job, specs, many, report=kill_one)
        rows[f"Dask, {n} workers, one killed"] = (time.perf_counter() - start, killed)
    print(f"campaign of {len(specs)} runs, scenario {args.scenario}, at most "
          f"{args.max_duration:.0f} s simulated each, {os.cpu_count()} cores here, best of "
          f"{args.rounds} interleaved rounds, load average {os.getloadavg()[0]:.1f}")
    print(f"{'executor':34s} {'wall s':>8s} {'runs/s':>7s} {'finished':>8s} {'failed':>6s}")
    for label, (wall, out) in rows.items():
        print(f"{label:34s} {wall:8.2f} {len(specs) / wall:7.2f} {out.finished:8d} "
              f"{len(out.failures):6d}")
    local = rows[f"local pool, {n} processes"][0]
    single = rows["Dask, 1 worker"][0]
    dask_n = rows[f"Dask, {n} workers"][0]
    lost = len(specs) - killed.finished - len(killed.failures)
    print(f"scaling, Dask {n} workers vs 1: {single / dask_n:.2f}x (goal >= 1.8x for 2)")
    print(f"overhead, Dask {n} workers vs local pool of {n}: {dask_n / local - 1:+.1%} "
          "(goal <= +5 %)")
    print(f"worker killed mid-campaign: {lost} runs lost, {len(killed.failures)} failed, "
          f"{killed.retried} resubmitted by hil (goal 0 lost)")
    return 0 if lost == 0 and not killed.failures else 1
