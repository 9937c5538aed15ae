"""Progress of a replay on stderr: a rich bar with the log and step, when stderr is a terminal.

Elsewhere (a pipe, a CI log, pytest's capture) it does nothing, so that what a
replay prints stays plain text.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.progress import Progress, TaskID


class ReplayProgress:
    """A progress bar over the logs of one replay, showing each log's current step.

    Args:
        total: Number of logs.
        enabled: Show it; default: when stderr is a terminal.
    """

    def __init__(self, total: int, enabled: bool | None = None) -> None:
        self.total = total
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self._progress: Progress | None = None
        self._task: TaskID | None = None

    def __enter__(self) -> ReplayProgress:
        if self.enabled and self.total:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TimeElapsedColumn,
            )

            # Reports printed meanwhile go above the bar; stdout only when it is the
            # terminal too (a redirected stdout keeps its reports).
            self._progress = Progress(
                "[progress.description]{task.description}",
                BarColumn(),
                MofNCompleteColumn(),
                TimeElapsedColumn(),
                console=Console(stderr=True),
                transient=True,
                redirect_stdout=sys.stdout.isatty(),
            )
            self._progress.__enter__()
            self._task = self._progress.add_task("replay", total=self.total)
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        value: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        if self._progress is not None:
            self._progress.__exit__(kind, value, traceback)
            self._progress = None

    def step(self, log: Path) -> Callable[[str], None]:
        """Return the callback that shows `log`'s current step ("load", "stack", ...)."""

        def show(name: str) -> None:
            if self._progress is not None and self._task is not None:
                self._progress.update(self._task, description=f"{log.name}: {name}")

        return show

    def done(self) -> None:
        """Count one log as replayed."""
        if self._progress is not None and self._task is not None:
            self._progress.advance(self._task)
