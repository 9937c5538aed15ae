"""The loader's rule for imperfect input, applied per topic, and the report of what it did.

Bad messages are left out, out-of-order ones put in stamp order, duplicates dropped
but the first; each is counted per topic as a :class:`Repair` (see
:mod:`hil.bag.run_data`).
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hil.core.arrays import IntArray

__all__ = ["Repair", "RepairKind", "tidy"]


class RepairKind(enum.Enum):
    """What the loader did to some messages of a topic (see the module docstring)."""

    BAD = "bad"
    REORDERED = "reordered"
    DUPLICATE = "duplicate"
    SAME_STAMP = "same_stamp"


@dataclass(frozen=True, slots=True)
class Repair:
    """Messages of one topic the loader left out, reordered or flagged.

    Attributes:
        topic: The topic.
        kind: What was done.
        count: How many messages.
        t_ns: Stamp of the first one (ns).
        detail: The first one's reason (bad messages) or the stamp it followed
            (reordered ones); "" otherwise.
    """

    topic: str
    kind: RepairKind
    count: int
    t_ns: int
    detail: str = ""

    def __str__(self) -> str:
        """Return the repair as one line."""
        what = {
            RepairKind.BAD: f"skipped {self.count} message(s) that do not decode to valid "
            f"samples, first t={self.t_ns} ns: {self.detail}",
            RepairKind.REORDERED: f"{self.count} stamp(s) go back in time, first at "
            f"t={self.t_ns} ns after t={self.detail} ns; put in stamp order",
            RepairKind.DUPLICATE: f"dropped {self.count} duplicated message(s), "
            f"first at t={self.t_ns} ns",
            RepairKind.SAME_STAMP: f"{self.count} message(s) share a stamp with different "
            f"values, first at t={self.t_ns} ns; all kept",
        }[self.kind]
        return f"{self.topic}: {what}"


def tidy(
    topic: str,
    t_ns: IntArray,
    same: Callable[[int, int], bool],
    repairs: list[Repair],
    *,
    report_ties: bool,
) -> NDArray[np.intp]:
    """Apply the rule to one topic: return the indices kept, in stamp order.

    Args:
        topic: Topic name (for the report).
        t_ns: Stamps in recorded order, shape (N,).
        same: Whether messages i and j (recorded indices) hold the same values.
        repairs: Where to add what was done.
        report_ties: Whether to report messages sharing a stamp with different values.
    """
    n = len(t_ns)
    order = np.arange(n, dtype=np.intp)
    if n < 2:
        return order
    back = np.flatnonzero(t_ns[1:] < t_ns[:-1])
    if back.size:
        repairs.append(
            Repair(
                topic,
                RepairKind.REORDERED,
                int(back.size),
                int(t_ns[back[0] + 1]),
                str(int(t_ns[back[0]])),
            )
        )
        order = np.argsort(t_ns, kind="stable").astype(np.intp)
    stamps = t_ns[order]
    tied = np.flatnonzero(stamps[1:] == stamps[:-1])
    if not tied.size:
        return order
    keep = np.ones(n, dtype=bool)
    dropped: list[int] = []
    clashes: list[int] = []
    start = 0
    while start < n:  # only runs of equal stamps need a look
        stop = start + 1
        while stop < n and stamps[stop] == stamps[start]:
            stop += 1
        for a in range(start + 1, stop):
            if any(keep[b] and same(int(order[b]), int(order[a])) for b in range(start, a)):
                keep[a] = False
                dropped.append(int(stamps[a]))
            else:
                clashes.append(int(stamps[a]))
        start = stop
    if dropped:
        repairs.append(Repair(topic, RepairKind.DUPLICATE, len(dropped), dropped[0]))
    if clashes and report_ties:
        repairs.append(Repair(topic, RepairKind.SAME_STAMP, len(clashes), clashes[0]))
    return order[keep]
