"""The Dask backend of :class:`hil.runs.executor.Executor`: runs on a Dask cluster.

Either a running cluster (``dask scheduler`` and ``dask worker`` processes on the
lab's machines, reached at ``tcp://HOST:PORT``) or one started here on local
processes (one thread each: a run is Python-bound and would hold the GIL). Every
worker, including one that joins or restarts later, warms once before its first
run (:class:`~hil.runs.executor.WarmedCall`). Dask reschedules the runs of a worker that dies; a run
whose workers keep dying ends as ``KilledWorker`` and is retried by the fan-out a
bounded number of times. When the scheduler goes away, the futures are cancelled:
that is :meth:`DaskExecutor.cluster_lost`.

Importing this module needs Dask (``pip install 'hil[dask]'``).
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from types import TracebackType
from typing import Any, TypeVar

import dask
import distributed
from distributed import Client, LocalCluster
from distributed.client import FutureCancelledError

from hil.runs.errors import ExecutorError
from hil.runs.executor import Warm, WarmedCall

__all__ = ["ClusterLostError", "DaskExecutor"]

S = TypeVar("S")
R = TypeVar("R")

_CAPACITY_REFRESH_S = 2.0
CONNECT_TIMEOUT_S = 20.0
"""How long to try reaching a scheduler (s)."""
WORKER_CONFIG = {"distributed.worker.profile.enabled": False}
"""Settings of the local cluster's workers: no statistical profiler, which samples the
running task's stack every 10 ms and takes the GIL from a Python-bound run to do it
(for `dask worker` elsewhere: DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED=False)."""
CLOSE_TIMEOUT_S = 5.0
"""How long to wait for a clean disconnect (s)."""
WORKERS_TIMEOUT_S = 120.0
"""How long to wait for the first worker to join the scheduler (s)."""


class ClusterLostError(ExecutorError):
    """The scheduler went away (or cancelled the run): no run can finish now."""


class DaskExecutor:
    """Runs calls on a Dask cluster.

    Args:
        scheduler: ``tcp://HOST:PORT`` of a running scheduler; None starts a local
            cluster of `workers` processes, one thread each.
        workers: Processes of the local cluster (unused with a scheduler).
        warm: Called once on every worker before its first run.
        workers_timeout_s: How long to wait for the first worker (s).
        connect_timeout_s: How long to try reaching the scheduler, and to try again
            once it is lost before the runs in flight count as lost (s).

    Raises:
        ExecutorError: The scheduler cannot be reached, or no worker joined it within
            :data:`WORKERS_TIMEOUT_S`.
    """

    def __init__(self, scheduler: str | None, workers: int = 1, warm: Warm | None = None,
                 workers_timeout_s: float = WORKERS_TIMEOUT_S,
                 connect_timeout_s: float = CONNECT_TIMEOUT_S) -> None:
        self._cluster: LocalCluster | None = None
        self._address = scheduler
        try:
            if scheduler is None:
                with dask.config.set(WORKER_CONFIG):
                    self._cluster = LocalCluster(n_workers=workers, threads_per_worker=1,
                                                 processes=True, dashboard_address=":0")
                self._client = Client(self._cluster)
            else:
                self._client = Client(scheduler, timeout=connect_timeout_s)
        except (OSError, TimeoutError) as err:
            self._close_cluster()
            where = scheduler or "a local cluster"
            raise ExecutorError(f"cannot reach the Dask scheduler at {where}: {err}") from err
        self._warm = warm
        try:
            self._client.wait_for_workers(1, timeout=workers_timeout_s)
        except (OSError, TimeoutError) as err:
            self.close()
            raise ExecutorError(
                f"no Dask worker joined the scheduler at {scheduler} within "
                f"{workers_timeout_s:.0f} s (start some with: dask worker {scheduler} "
                f"--nthreads 1 --nworkers N)") from err
        self._futures: dict[Future[Any], distributed.Future] = {}
        self._lock = threading.Lock()
        self._capacity = 1
        self._capacity_at = -math.inf  # never read yet

    def wait_for_workers(self, n: int, timeout_s: float = WORKERS_TIMEOUT_S) -> None:
        """Block until `n` workers have joined.

        Raises:
            ExecutorError: They did not within `timeout_s`.
        """
        try:
            self._client.wait_for_workers(n, timeout=timeout_s)
        except TimeoutError as err:
            raise ExecutorError(f"fewer than {n} Dask workers joined in {timeout_s} s") from err

    @property
    def client(self) -> Client:
        """Return the Dask client (to inspect the cluster: workers, tasks in flight)."""
        return self._client

    @property
    def description(self) -> str:
        """Say where runs execute."""
        if self._cluster is not None:
            return f"a local Dask cluster of {len(self._cluster.workers)} processes"
        return f"the Dask cluster at {self._address} ({self.capacity()} threads)"

    @property
    def dashboard(self) -> str | None:
        """Return the dashboard's link, when the scheduler serves one (it needs bokeh)."""
        try:
            services = self._client.scheduler_info(n_workers=0).get("services", {})
        except (OSError, TimeoutError):
            return None
        link = self._client.dashboard_link if "dashboard" in services else None
        return str(link) if link else None

    @property
    def batches(self) -> bool:
        """Return True: a Dask task costs milliseconds of scheduler and client time."""
        return True

    def capacity(self) -> int:
        """Return the threads of every worker now in the cluster (refreshed every 2 s)."""
        now = time.monotonic()
        if now - self._capacity_at > _CAPACITY_REFRESH_S:
            # A scheduler gone shows in the runs' futures, not here.
            with contextlib.suppress(OSError, TimeoutError):
                self._capacity = max(1, sum(self._client.nthreads().values()))
            self._capacity_at = now
        return self._capacity

    def submit(self, fn: Callable[[S], R], item: S) -> Future[R]:
        """Submit ``fn(item)`` (never deduplicated: every call runs)."""
        result: Future[R] = Future()
        remote = self._client.submit(WarmedCall(fn, self._warm), item, pure=False)
        with self._lock:
            self._futures[result] = remote
        remote.add_done_callback(lambda done: self._settle(done, result))
        return result

    def _settle(self, remote: distributed.Future, result: Future[Any]) -> None:
        """Pass a finished Dask future's outcome on (in Dask's callback thread)."""
        with self._lock:
            self._futures.pop(result, None)
        try:
            status = remote.status
            if status == "finished":
                result.set_result(remote.result())
            elif status == "cancelled":
                result.set_exception(ClusterLostError(
                    f"the Dask scheduler at {self._address or 'the local cluster'} cancelled "
                    "the run (connection lost)"))
            else:
                error = remote.exception()
                result.set_exception(error if isinstance(error, BaseException)
                                     else RuntimeError(f"run failed: {error!r}"))
        except (FutureCancelledError, OSError) as err:
            result.set_exception(ClusterLostError(f"lost the Dask scheduler: {err}"))
        except Exception as err:  # the result could not be fetched
            result.set_exception(err)

    def worker_lost(self, error: BaseException) -> bool:
        """Whether the run's workers kept dying (Dask's KilledWorker)."""
        return isinstance(error, distributed.KilledWorker)

    def cluster_lost(self, error: BaseException) -> bool:
        """Whether the scheduler went away."""
        return isinstance(error, ClusterLostError)

    def close(self) -> None:
        """Disconnect (and stop the local cluster, if this started one)."""
        client = getattr(self, "_client", None)
        if client is not None:
            client.close(timeout=CLOSE_TIMEOUT_S)
        self._close_cluster()

    def _close_cluster(self) -> None:
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def __enter__(self) -> DaskExecutor:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()
