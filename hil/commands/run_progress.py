"""What `hil run`'s spinner says: the stage the run is in, from the records it makes.

:class:`StageLog` sits between the runtime and the run's log (a live view, as
``--rerun`` does) and passes every record on; from the controllers taken and the
decisions made it tells which stage the run is in ("synthesizing the first
controller", then "docking, 12.0 s simulated, 6 decisions, ...") and where its
controllers came from (solved, stored, memory).
"""

from __future__ import annotations

from collections.abc import Callable

from hil.core.records import ControllerReady, ControllerSource, Decision
from hil.core.samples import PoseSample
from hil.runtime.log_relay import RunLogRelay
from hil.runtime.protocols import RunLog

_SOURCE_WORDS = {
    ControllerSource.SOLVED: "solved",
    ControllerSource.STORE: "stored",
    ControllerSource.MEMORY: "memory",
    ControllerSource.UNKNOWN: "unknown",
}
"""Short words, so that the spinner's line fits an 80-column terminal."""


class StageLog(RunLogRelay):
    """A run log that says the run's stage through `show` and passes every record on.

    Args:
        inner: The log that keeps the records (recorder, memory, live view).
        show: Called with the stage's text whenever it changes (a spinner's update).
        what: The run in words ("coarse, seed 0").
    """

    def __init__(self, inner: RunLog, show: Callable[[str], None], what: str) -> None:
        super().__init__(inner)
        self.show = show
        self.what = what
        self.sources: dict[ControllerSource, int] = {}
        self.decisions = 0
        self.start_ns: int | None = None
        self.show(f"{what}: synthesizing the first controller (or reading the store)")

    def _sources_text(self) -> str:
        return ", ".join(
            f"{n} {_SOURCE_WORDS[source]}" for source, n in sorted(self.sources.items()) if n
        )

    def _docking(self, t_ns: int) -> None:
        start = self.start_ns if self.start_ns is not None else t_ns
        taken = sum(self.sources.values())
        self.show(
            f"{self.what}: docking, {(t_ns - start) / 1e9:.1f} s simulated, "
            f"{self.decisions} decisions, {taken} controllers ({self._sources_text()})"
        )

    def pose(self, sample: PoseSample) -> None:
        """Pass a pose sample on; the first one starts the run's clock."""
        if self.start_ns is None:
            self.start_ns = sample.t_ns
        self.inner.pose(sample)

    def decision(self, record: Decision) -> None:
        """Pass a decision on and count it."""
        self.decisions += 1
        self.inner.decision(record)
        self._docking(record.t_ns)

    def controller_ready(self, record: ControllerReady) -> None:
        """Pass a controller taken on and count where it came from (full ones)."""
        if record.complete:
            self.sources[record.source] = self.sources.get(record.source, 0) + 1
        self.inner.controller_ready(record)
        self._docking(record.t_ns)
