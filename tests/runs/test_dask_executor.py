"""Campaigns on a real Dask cluster: a `dask scheduler` and two `dask worker` processes on loopback.

The same runs as in this process give the same summaries; a worker killed mid-campaign
loses no run; a scheduler killed mid-campaign keeps every finished run in the results
file, and a resume finishes the campaign without redoing them.
"""

from __future__ import annotations

import math
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from hil.controllers.symbolic.sources import ControllerSources
from hil.runs.campaign import CampaignRun, sim_job
from hil.runs.dask_executor import DaskExecutor
from hil.runs.executor import LocalExecutor
from hil.runs.fanout import fan_out
from hil.runs.results import Plan, ResultStream
from hil.runs.sim_run import SimRunSpec
from hil.runtime.settings import LoopConfig

ROOT = Path(__file__).resolve().parents[2]

# Short runs of the coarse scenario (at most 60 s simulated, about 0.3 s each): from the
# default start and two of the suite's, at rest and moving, some docking, one not.
BASE = SimRunSpec(scenario="coarse", loop=LoopConfig(resynthesis_period_s=None,
                                                      max_duration_s=60.0))
STARTS = [None, (0.25, -1.2, math.radians(120.0)), (0.0, -1.0, math.pi), (0.25, 2.0, 0.0)]
SPECS = [replace(BASE, seed=i, start=STARTS[i % 4],
                 start_velocity=None if i % 3 else (0.05, 0.0, 0.0)) for i in range(10)]
JOB = sim_job("campaign", ["coarse"])


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class Cluster:
    """A scheduler and two workers, as subprocesses of the test, on loopback."""

    port: int
    scheduler: subprocess.Popen[bytes] | None = None
    workers: list[subprocess.Popen[bytes]] = field(default_factory=list)

    @property
    def address(self) -> str:
        return f"tcp://127.0.0.1:{self.port}"

    def ensure(self) -> None:
        """Start what is not running: the scheduler, and workers up to two."""
        if self.scheduler is None or self.scheduler.poll() is not None:
            self.stop()  # workers of a lost scheduler: start afresh
            self.workers = []
            self.scheduler = _start(["scheduler", "--host", "127.0.0.1", "--port",
                                     str(self.port), "--no-dashboard"])
        self.workers = [w for w in self.workers if w.poll() is None]
        while len(self.workers) < 2:
            self.workers.append(_start([
                "worker", self.address, "--nthreads", "1", "--no-nanny", "--no-dashboard",
                "--host", "127.0.0.1", "--death-timeout", "10"]))

    def stop(self) -> None:
        for proc in [*self.workers, *([self.scheduler] if self.scheduler else [])]:
            if proc.poll() is None:
                proc.kill()
            proc.wait(timeout=30)


def _start(args: list[str]) -> subprocess.Popen[bytes]:
    """Start ``python -m dask ARGS``; its log goes to $HIL_TEST_DASK_LOGS/ when set."""
    # The workers import this checkout's hil (and warm its numba cache, shared).
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get(
        "PYTHONPATH", "")])}
    logs = os.environ.get("HIL_TEST_DASK_LOGS")
    if not logs:
        return subprocess.Popen([sys.executable, "-m", "dask", *args], env=env, cwd=ROOT,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    Path(logs).mkdir(parents=True, exist_ok=True)
    with (Path(logs) / f"{args[0]}-{time.time_ns()}.log").open("wb") as log:
        return subprocess.Popen([sys.executable, "-m", "dask", *args], env=env, cwd=ROOT,
                                stdout=log, stderr=subprocess.STDOUT)


@pytest.fixture(scope="module")
def local_runs() -> list[CampaignRun]:
    """The runs in this process (it also fills the numba cache the workers then load)."""
    with LocalExecutor(1, JOB.warm) as local:
        out = fan_out(JOB, SPECS, local)
    assert out.complete
    return [r for r in out.results if r is not None]


@pytest.fixture(scope="module")
def running(local_runs: list[CampaignRun]) -> Iterator[Cluster]:
    """One cluster for the module; each test gets it whole again (:func:`cluster`)."""
    cluster = Cluster(_free_port())
    try:
        yield cluster
    finally:
        cluster.stop()


@pytest.fixture
def cluster(running: Cluster) -> Cluster:
    running.ensure()
    return running


def _open(cluster: Cluster) -> DaskExecutor:
    dask = DaskExecutor(cluster.address, warm=JOB.warm, connect_timeout_s=5.0)
    dask.wait_for_workers(2)
    return dask


def _without_process_facts(run: CampaignRun) -> CampaignRun:
    """The run without what depends on the process that ran it: wall-clock times, and
    where its controller came from (solved, the store, or a process that already held it)."""
    summary, violations = run
    return replace(summary, wall_s=0.0, synthesis_mean_s=0.0, synthesis_max_s=0.0,
                   sources=ControllerSources()), violations


def test_dask_gives_the_local_summaries_and_streams_each_run(
        cluster: Cluster, local_runs: list[CampaignRun], tmp_path: Path) -> None:
    plan = Plan.of("campaign", [JOB.encode_spec(s) for s in SPECS])
    with _open(cluster) as dask, ResultStream(tmp_path / "results.jsonl", plan) as stream:
        assert dask.capacity() == 2
        out = fan_out(JOB, SPECS, dask, stream)
    assert out.complete
    assert not out.failures
    assert not out.stopped
    assert [_without_process_facts(r) for r in out.results if r is not None] == \
        [_without_process_facts(r) for r in local_runs]
    assert any(r[0].docked for r in local_runs)
    assert not all(r[0].docked for r in local_runs)
    lines = (tmp_path / "results.jsonl").read_text().splitlines()
    assert len(lines) == 1 + len(SPECS)
    # Read back exactly, wall-clock fields included.
    again = ResultStream(tmp_path / "results.jsonl", plan, resume=True).open()
    again.close()
    assert [JOB.decode_result(again.finished[i]) for i in range(len(SPECS))] == out.results


def test_a_worker_killed_mid_campaign_loses_no_run(
        cluster: Cluster, local_runs: list[CampaignRun]) -> None:
    victim = cluster.workers[0]
    ended: list[int] = []
    taken: list[int] = []  # runs in flight on the victim when it was killed

    with _open(cluster) as dask:

        def kill_after_the_first(index: int, _outcome: object) -> None:
            ended.append(index)
            if len(ended) == 1:
                pids = dask.client.run(os.getpid)
                address = next(a for a, pid in pids.items() if pid == victim.pid)
                taken.append(len(dask.client.processing()[address]))
                victim.send_signal(signal.SIGKILL)

        out = fan_out(JOB, SPECS, dask, report=kill_after_the_first)
    assert victim.wait(timeout=10) == -signal.SIGKILL
    assert taken[0] >= 1
    assert out.complete
    assert not out.failures
    assert not out.stopped
    assert sorted(ended) == list(range(len(SPECS)))
    assert [_without_process_facts(r) for r in out.results if r is not None] == \
        [_without_process_facts(r) for r in local_runs]


def test_replay_on_the_cluster_ships_the_bags_and_gives_the_local_reports(
        cluster: Cluster) -> None:
    from hil.replay.job import REPLAY_JOB, replay_task, task_for
    from hil.replay.options import ReplayOptions
    from hil.replay.regression import LogReport

    logs = [ROOT / "logs" / "coarse-default-seed0", ROOT / "logs" / "coarse-faults-seed4"]
    options = ReplayOptions(stack=False)
    tasks = [task_for(log, options, ship=True) for log in logs]
    assert all(t.files for t in tasks)

    def verdicts(report: LogReport) -> object:
        # Not the wall time, nor how many controllers this process had to synthesize.
        return (report.path, report.error, report.warnings,
                [(c.name, c.status, c.findings) for c in report.checks])

    local = [replay_task(task_for(log, options, ship=False)) for log in logs]
    assert not any(r.error for r in local)
    with _open(cluster) as dask:
        out = fan_out(REPLAY_JOB, tasks, dask)
    assert out.complete
    assert [verdicts(r) for r in out.results if r is not None] == [verdicts(r) for r in local]
    assert [r.path for r in out.results if r is not None] == [str(log) for log in logs]


def test_a_lost_scheduler_keeps_the_finished_runs_and_a_resume_finishes(
        cluster: Cluster, local_runs: list[CampaignRun], tmp_path: Path) -> None:
    plan = Plan.of("campaign", [JOB.encode_spec(s) for s in SPECS])
    path = tmp_path / "results.jsonl"
    ended: list[int] = []

    def kill_the_scheduler(index: int, _outcome: object) -> None:
        ended.append(index)
        if len(ended) == 2:
            assert cluster.scheduler is not None
            cluster.scheduler.send_signal(signal.SIGKILL)

    with _open(cluster) as dask, ResultStream(path, plan) as stream:
        out = fan_out(JOB, SPECS, dask, stream, kill_the_scheduler)
    assert out.stopped
    assert "scheduler" in out.stopped
    assert 2 <= out.finished < len(SPECS)
    assert len(path.read_text().splitlines()) == 1 + out.finished
    # Resume on local processes: the finished runs are read back, the others run.
    with ResultStream(path, plan, resume=True) as stream, LocalExecutor(1, JOB.warm) as local:
        again = fan_out(JOB, SPECS, local, stream)
    assert again.resumed == out.finished
    assert again.complete
    assert not again.failures
    assert [_without_process_facts(r) for r in again.results if r is not None] == \
        [_without_process_facts(r) for r in local_runs]
    assert len(path.read_text().splitlines()) == 1 + len(SPECS)
