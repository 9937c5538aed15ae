"""Where a synthesizer's controllers came from: solved, from the store, from memory."""

from __future__ import annotations

from dataclasses import dataclass, replace

from hil.core.records import ControllerSource

__all__ = ["ControllerSources"]


@dataclass(slots=True)
class ControllerSources:
    """Where a synthesizer's controllers came from, counted per request.

    Attributes:
        solved: Solved here (the fixed point ran).
        store: Read from the solved-controller store on disk.
        memory: Reused from this process's memo.
    """

    solved: int = 0
    store: int = 0
    memory: int = 0

    def total(self) -> int:
        """Return the number of controllers handed out."""
        return self.solved + self.store + self.memory

    def minus(self, before: ControllerSources) -> ControllerSources:
        """Return the counts since `before` (a copy taken earlier)."""
        return ControllerSources(
            self.solved - before.solved, self.store - before.store, self.memory - before.memory
        )

    def copy(self) -> ControllerSources:
        """Return a snapshot of the counts."""
        return replace(self)

    def source_since(self, before: ControllerSources) -> ControllerSource:
        """Return where the one controller handed out since `before` came from.

        Meant for one request between two snapshots on the synthesizer's only caller
        (the runtime's solver thread); a solve that yielded nothing counts as solved.
        """
        since = self.minus(before)
        if since.memory:
            return ControllerSource.MEMORY
        if since.store:
            return ControllerSource.STORE
        return ControllerSource.SOLVED

    def describe(self) -> str:
        """Return the counts as text, e.g. ``2 solved, 1 from the store``."""
        parts = [f"{self.solved} solved"]
        if self.store:
            parts.append(f"{self.store} from the store")
        if self.memory:
            parts.append(f"{self.memory} from memory")
        return ", ".join(parts)
