"""A replay worker warms numba's cache with a run only while that cache is cold."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.core import jit
from hil.replay import job
from hil.runs.executor import WarmedCall, warm_key


def test_a_replay_worker_runs_no_warm_up_once_the_cache_is_warm(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    runs: list[tuple[str, ...]] = []
    monkeypatch.setattr(jit, "CACHE_DIR", tmp_path)  # a cold numba cache
    monkeypatch.setattr(job, "warm_sim", runs.append)
    assert job.REPLAY_JOB.warm is job.warm_replay
    assert not jit.warmed(warm_key(job.warm_replay))
    jit.warm_once(warm_key(job.warm_replay), job.warm_replay)  # the first worker
    assert runs == [("coarse",)]
    assert jit.warmed(warm_key(job.warm_replay))
    jit.warm_once(warm_key(job.warm_replay), job.warm_replay)  # every later one
    job.warm_replay()
    assert runs == [("coarse",)]
    # Through the executor's wrapper, as a pool or Dask worker calls it.
    assert WarmedCall(len, job.REPLAY_JOB.warm)("abc") == 3
    assert runs == [("coarse",)]
