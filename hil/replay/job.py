"""The replay of one log as a job of :func:`hil.runs.fanout.fan_out` (``hil replay --workers``).

A :class:`ReplayTask` is what a worker needs: the log's path, or its files' bytes
when the worker may be another machine (a Dask cluster at ``--scheduler``: the bag
is written to a temporary folder there and replayed from it), and the options.
Each worker process keeps its controllers across the logs it replays (one
:class:`~hil.replay.controllers.ScenarioCache`), as a replay in one process does.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

from hil.core.jit import warmed
from hil.replay.controllers import ScenarioCache
from hil.replay.options import ReplayOptions
from hil.replay.regression import LogReport
from hil.replay.replayer import replay_log
from hil.runs.campaign import warm_sim
from hil.runs.executor import warm_key
from hil.runs.fanout import Job

__all__ = [
    "REPLAY_JOB", "ReplayTask", "process_caches", "replay_task", "task_for", "warm_replay",
]  # fmt: skip

_CACHES: dict[Path | None, ScenarioCache] = {}


@dataclass(frozen=True, slots=True)
class ReplayTask:
    """One log to replay.

    Attributes:
        path: The log as given (the report names it).
        options: What to check.
        files: The bag's files by path relative to `path` (a storage file: its name),
            shipped to a worker that cannot read `path`; None replays `path` itself.
        directory: Whether `path` is a bag directory (else a storage file).
    """

    path: str
    options: ReplayOptions
    files: dict[str, bytes] | None = None
    directory: bool = True


def task_for(path: Path, options: ReplayOptions, *, ship: bool) -> ReplayTask:
    """Return the task of `path`, with its files' bytes if `ship` (and it can be read)."""
    if not ship or not path.exists():
        return ReplayTask(str(path), options)
    try:
        if path.is_dir():
            files = {str(p.relative_to(path)): p.read_bytes()
                     for p in sorted(path.rglob("*")) if p.is_file()}
        else:
            files = {path.name: path.read_bytes()}
    except OSError:
        return ReplayTask(str(path), options)  # unreadable: the replay says why
    return ReplayTask(str(path), options, files, path.is_dir())


def process_caches(cache_dir: Path | None = None) -> ScenarioCache:
    """Return this process's controllers for the replays of tables in `cache_dir`."""
    return _CACHES.setdefault(cache_dir, ScenarioCache(cache_dir))


def replay_task(task: ReplayTask) -> LogReport:
    """Replay `task` (never raises for a bad or foreign log, as :func:`replay_log`)."""
    caches = process_caches(task.options.cache_dir)
    if task.files is None:
        return replay_log(task.path, task.options, caches)
    with tempfile.TemporaryDirectory(prefix="hil-replay-") as tmp:
        root = Path(tmp) / (Path(task.path).name or "log") if task.directory else Path(tmp)
        root.mkdir(exist_ok=True)
        for relative, data in task.files.items():
            target = root / relative
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
        local = root if task.directory else root / next(iter(task.files))
        report = replay_log(local, task.options, caches)
    return replace(report, path=task.path)


def _encode_task(task: ReplayTask) -> object:
    return {"path": task.path}


def _no_decode(data: object) -> LogReport:
    raise TypeError(f"replay reports are not read back from a results file: {data!r}")


def _no_encode(report: LogReport) -> object:
    return {"path": report.path}


def warm_replay() -> None:
    """Prepare a replay worker: nothing once numba's cache holds this source tree's kernels.

    A replay needs no warm-up run for its controllers (they come from the
    solved-controller store, or are solved on first use) nor for numba's kernels
    once they are cached: each loads on its first call. Only while that cache is cold
    (the first replay after an edit of the package) does the first worker compile
    them in one short run of the coarse scenario, the others waiting on the cache
    lock (:func:`hil.core.jit.warm_once`), so that workers started together compile once.
    """
    if not warmed(warm_key(warm_replay)):
        warm_sim(("coarse",))


REPLAY_JOB: Job[ReplayTask, LogReport] = Job(
    "replay", replay_task, _encode_task, _no_encode, _no_decode, warm_replay)
"""Replay logs; each worker first warms numba's cache if it is cold (:func:`warm_replay`)."""
