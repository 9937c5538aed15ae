"""Choose and open an executor (:class:`hil.runs.executor.Executor`) from a small table.

``local`` (:class:`~hil.runs.executor.LocalExecutor`) by default; ``dask``
(:class:`~hil.runs.dask_executor.DaskExecutor`) with ``--dask`` or ``--scheduler``,
imported only then, so that Dask stays an optional extra.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from hil.runs.errors import ExecutorError
from hil.runs.executor import Executor, LocalExecutor, Warm

__all__ = ["BACKENDS", "DASK_MISSING", "ExecutorChoice", "open_executor", "require_backend"]

DASK_MISSING = ("--dask and --scheduler need Dask, which is not installed; install the extra: "
                "pip install -e '.[dask]' (python3 tools/dev.py installs it)")
"""The one line that says how to get the optional Dask backend."""


@dataclass(frozen=True, slots=True)
class ExecutorChoice:
    """Which executor a command asked for.

    Attributes:
        workers: Local processes (local backend, or a local Dask cluster).
        dask: Use Dask (a local cluster of `workers` processes unless `scheduler`).
        scheduler: Address of a running Dask scheduler (``tcp://HOST:PORT``); implies Dask.
    """

    workers: int = 1
    dask: bool = False
    scheduler: str | None = None

    @property
    def backend(self) -> str:
        """Return the key in :data:`BACKENDS`."""
        return "dask" if self.dask or self.scheduler is not None else "local"


def _open_local(choice: ExecutorChoice, warm: Warm | None) -> Executor:
    return LocalExecutor(choice.workers, warm)


def _open_dask(choice: ExecutorChoice, warm: Warm | None) -> Executor:
    try:
        from hil.runs.dask_executor import DaskExecutor
    except ImportError as err:  # the optional extra is missing
        raise ExecutorError(DASK_MISSING) from err
    return DaskExecutor(choice.scheduler, choice.workers, warm)


BACKENDS: dict[str, Callable[[ExecutorChoice, Warm | None], Executor]] = {
    "local": _open_local,
    "dask": _open_dask,
}
"""Backend name -> how to open it."""


def require_backend(choice: ExecutorChoice) -> None:
    """Check, before any work, that `choice`'s backend can be imported.

    Raises:
        ExecutorError: Dask asked for but not installed (:data:`DASK_MISSING`).
    """
    if choice.backend == "dask":
        try:
            import hil.runs.dask_executor  # noqa: F401 - imported to see that Dask is there
        except ImportError as err:
            raise ExecutorError(DASK_MISSING) from err


def open_executor(choice: ExecutorChoice, warm: Warm | None = None) -> Executor:
    """Open the executor `choice` names.

    Raises:
        ExecutorError: Dask asked for but not installed, its scheduler unreachable,
            or no worker joined it in time (one line saying which).
    """
    if choice.workers < 1:
        raise ExecutorError(f"--workers must be at least 1, got {choice.workers!r}")
    return BACKENDS[choice.backend](choice, warm)
