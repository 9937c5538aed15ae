"""Solved controllers kept in memory up to a byte budget, least recently used dropped first.

A paper-grid controller holds about 300 MB (winning bits, value planes, viable words,
safety set); a run with moving obstacles meets a new layout every report, so keeping
every one (a replay's checks, a simulated run's judge) outgrows the machine within a
minute of tank time. Holders keep a few here and solve a dropped one again, which the
solved-controller store makes a read (:mod:`hil.controllers.symbolic.store`).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Hashable
from typing import Generic, TypeVar

from hil.controllers.symbolic import Controller

__all__ = ["DEFAULT_BUDGET_BYTES", "ControllerLru"]

DEFAULT_BUDGET_BYTES = 3 * 2**30
"""What the kept controllers may hold together: about ten paper-grid ones, a few
hundred coarse ones; well inside this 24-GiB machine and the Pi's 8 GB."""

T = TypeVar("T")


class ControllerLru(Generic[T]):
    """Values (a controller or what wraps one) by key, at most `budget` bytes of controllers.

    Args:
        budget: Largest total :attr:`Controller.nbytes` kept; the newest value is always
            kept, whatever its size.
    """

    def __init__(self, budget: int = DEFAULT_BUDGET_BYTES) -> None:
        self.budget = budget
        self._items: OrderedDict[Hashable, tuple[T, int]] = OrderedDict()
        self._bytes = 0

    def get(self, key: Hashable) -> T | None:
        """Return the value under `key` (now the most recently used), None if not kept."""
        item = self._items.get(key)
        if item is None:
            return None
        self._items.move_to_end(key)
        return item[0]

    def put(self, key: Hashable, value: T, controller: Controller | None) -> None:
        """Keep `value` (holding `controller`, whose bytes count; None: nothing counts)."""
        if key in self._items:
            self._bytes -= self._items.pop(key)[1]
        size = 0 if controller is None else controller.nbytes
        self._items[key] = (value, size)
        self._bytes += size
        while self._bytes > self.budget and len(self._items) > 1:
            _, (_, dropped) = self._items.popitem(last=False)
            self._bytes -= dropped

    def __len__(self) -> int:
        return len(self._items)
