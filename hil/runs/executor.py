"""Where runs execute: the one seam between a fan-out of jobs and the machines that run them.

:class:`Executor` is what :func:`hil.runs.fanout.fan_out` needs of a backend: submit
a picklable call and get a :class:`concurrent.futures.Future`, say how many calls run
at once, and tell a lost worker (retry the run) and a lost cluster (stop, keep what
finished) from a run that failed. Two backends, chosen from :data:`BACKENDS` by
:func:`open_executor`:

- ``local``: this process (one worker) or spawned processes
  (:class:`~concurrent.futures.ProcessPoolExecutor`), the default;
- ``dask``: a Dask cluster (:mod:`hil.runs.dask_executor`), at a scheduler's address or
  started here on local processes; an optional extra (``pip install 'hil[dask]'``).

Each worker process calls the job's `warm` once before its first run (numba's
kernels loaded or compiled, the abstraction tables read: :class:`WarmedCall`);
until one warm has finished against the cache, they take turns
(:func:`hil.core.jit.warm_once`), so workers that start together compile once and
never race on the cache.
"""

from __future__ import annotations

import functools
import multiprocessing
import signal
import threading
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from types import TracebackType
from typing import Generic, Protocol, TypeVar

from hil.core.jit import warm_once

__all__ = ["Executor", "LocalExecutor", "Warm", "WarmedCall", "ignore_sigint", "warm_key"]

S = TypeVar("S")
R = TypeVar("R")

Warm = Callable[[], None]
"""Prepares a worker process for its first run (picklable: a module function or partial)."""

class Executor(Protocol):
    """Runs picklable calls somewhere: local processes or a cluster.

    Works as a context manager; :meth:`close` releases the workers.
    """

    @property
    def description(self) -> str:
        """Say where runs execute, in a few words ("2 local processes")."""

    @property
    def dashboard(self) -> str | None:
        """Return the address of a live dashboard, if the backend has one."""

    @property
    def batches(self) -> bool:
        """Whether several short runs should go to a worker in one call (costly calls)."""

    def capacity(self) -> int:
        """Return how many calls can run at once now (at least 1)."""

    def submit(self, fn: Callable[[S], R], item: S) -> Future[R]:
        """Start ``fn(item)`` on some worker; the future holds its result or exception."""

    def worker_lost(self, error: BaseException) -> bool:
        """Whether `error` means the call's worker died (the call itself did not fail)."""

    def cluster_lost(self, error: BaseException) -> bool:
        """Whether `error` means the whole backend is gone (no call can finish now)."""

    def close(self) -> None:
        """Release the workers; calls still running are waited for."""

    def __enter__(self) -> Executor: ...

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 traceback: TracebackType | None) -> None: ...


def ignore_sigint() -> None:
    """Leave Ctrl-C to the parent (a pool process's initializer).

    Ctrl-C in a terminal reaches every process of the foreground group; the parent
    decides (the runs in flight finish), so a worker ignores it.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def warm_key(warm: Warm) -> str:
    """Name a warm-up by its function and arguments (stable across processes)."""
    args = ""
    if isinstance(warm, functools.partial):
        args = repr((warm.args, sorted(warm.keywords.items())))
        warm = warm.func
    return f"{getattr(warm, '__module__', '')}.{getattr(warm, '__qualname__', repr(warm))}{args}"


_WARMED: set[str] = set()
_WARM_LOCK = threading.Lock()


@dataclass(frozen=True, slots=True)
class WarmedCall(Generic[S, R]):
    """`fn`, preceded in each process by one `warm` (what an executor ships to a worker).

    The warm runs inside the first call a process gets, in the worker's own thread:
    a Dask worker's event loop stays free to answer the scheduler while numba
    compiles, and a worker that joins (or restarts) later warms too. Workers of one
    machine take turns until the first warm has filled the cache
    (:func:`hil.core.jit.warm_once`).

    Attributes:
        fn: The call.
        warm: Prepares the process; None for nothing.
    """

    fn: Callable[[S], R]
    warm: Warm | None = None

    def __call__(self, item: S) -> R:
        """Warm this process if it is the first call here, then return ``fn(item)``."""
        if self.warm is not None:
            key = warm_key(self.warm)
            with _WARM_LOCK:
                if key not in _WARMED:
                    warm_once(key, self.warm)
                    _WARMED.add(key)
        return self.fn(item)


class LocalExecutor:
    """Runs calls in this process (``workers == 1``) or in spawned processes.

    Spawned, not forked: the parent has run numba's threaded kernels, and a forked
    child of a threaded process may crash in the threading layer. A pool whose
    process died (killed, out of memory) is replaced on the next submit, so the
    runs it held are retried (:meth:`worker_lost` says so of their error).

    Args:
        workers: Processes (1: run in this process, no pool).
        warm: Called once per process before its first call.
    """

    def __init__(self, workers: int, warm: Warm | None = None) -> None:
        if workers < 1:
            raise ValueError(f"workers must be at least 1, got {workers!r}")
        self._workers = workers
        self._warm = warm
        self._pool: ProcessPoolExecutor | None = None

    @property
    def description(self) -> str:
        """Say where runs execute."""
        if self._workers == 1:
            return "this process"
        return f"{self._workers} local processes"

    @property
    def dashboard(self) -> str | None:
        """Return None: local processes have no dashboard."""
        return None

    @property
    def batches(self) -> bool:
        """Return False: a call to a pool process costs well under a millisecond."""
        return False

    def capacity(self) -> int:
        """Return the number of processes."""
        return self._workers

    def _new_pool(self) -> ProcessPoolExecutor:
        context = multiprocessing.get_context("spawn")
        return ProcessPoolExecutor(max_workers=self._workers, mp_context=context,
                                   initializer=ignore_sigint)

    def submit(self, fn: Callable[[S], R], item: S) -> Future[R]:
        """Run ``fn(item)``: at once in this process, or queued to the pool."""
        call = WarmedCall(fn, self._warm)
        if self._workers == 1:
            future: Future[R] = Future()
            try:
                future.set_result(call(item))
            except Exception as err:  # the run's failure, reported with its spec
                future.set_exception(err)
            return future
        if self._pool is None:
            self._pool = self._new_pool()
        try:
            return self._pool.submit(call, item)
        except BrokenProcessPool:
            # A worker died: the pool refuses work; its runs fail with BrokenProcessPool
            # and are resubmitted here, to a fresh pool.
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = self._new_pool()
            return self._pool.submit(call, item)

    def worker_lost(self, error: BaseException) -> bool:
        """Whether a pool process died under the call."""
        return isinstance(error, BrokenProcessPool)

    def cluster_lost(self, error: BaseException) -> bool:
        """Return False: local processes are replaced, never lost as a whole."""
        del error
        return False

    def close(self) -> None:
        """Shut the pool down, waiting for the calls still running."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def __enter__(self) -> LocalExecutor:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()
