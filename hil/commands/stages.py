"""What a long command is doing, said as it goes: one line per stage, with true times.

Each stage prints ``hil CMD: <what> ...`` when it starts (flushed at once, so that the
first line comes before any heavy import), and on a terminal a spinner with the
stage's elapsed time while it runs (rich, transient). :meth:`Stages.total_s` is the
wall time since the command started, what the last line reports.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TextIO


class Stages:
    """Say the stages of one command on `stream` (stderr by default).

    Args:
        prog: The command as the user typed it ("hil synth"); starts every line.
        stream: Where the lines go; None for stderr (stdout stays the command's report).
        spinner: Show a spinner with elapsed time during a stage; default: when
            `stream` is a terminal.
    """

    def __init__(
        self, prog: str, stream: TextIO | None = None, spinner: bool | None = None
    ) -> None:
        self.prog = prog
        self.stream = stream
        self.spinner = self._stream().isatty() if spinner is None else spinner
        self._start_s = time.perf_counter()

    def _stream(self) -> TextIO:
        return sys.stderr if self.stream is None else self.stream

    def say(self, text: str) -> None:
        """Print ``<prog>: <text>`` at once."""
        print(f"{self.prog}: {text}", file=self._stream(), flush=True)

    def total_s(self) -> float:
        """Return the wall time since the command started (s)."""
        return time.perf_counter() - self._start_s

    @contextmanager
    def stage(self, text: str) -> Iterator[None]:
        """Say ``<text> ...``, then run the block under a spinner with its elapsed time."""
        self.say(f"{text} ...")
        if not self.spinner:
            yield
            return
        from rich.console import Console
        from rich.progress import Progress, SpinnerColumn, TimeElapsedColumn

        with Progress(
            SpinnerColumn(),
            "[progress.description]{task.description}",
            TimeElapsedColumn(),
            console=Console(file=self._stream()),
            transient=True,
        ) as progress:
            progress.add_task(text, total=None)
            yield
