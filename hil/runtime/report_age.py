"""How old an obstacle report each new controller is solved for, from the ages measured.

A controller for obstacles that move avoids where each may be up to A + tau + late after
the report it was solved from; a decision may rely on that report while it is at most A
old (:meth:`hil.runtime.loop.Runtime`'s ``obstacles_stale`` check). A is fixed when the
layout is submitted and recorded with every decision of that controller, so a replay
solves the same growth.

Stated (``[obstacle_motion] report_age = "stated"``, the default): A is the scenario's
``max_report_age_s``. Measured (``report_age = "measured"``): the runtime measures on its
own clock

- L, the latency of each new layout's controller put in force: from its report's stamp
  to the tick it went in force (the wait for a busy solver and the solve itself, on this
  machine);
- I, the interval between consecutive reports taken in (the tracker's period);
- S, the age each relied-on report had when a fresher one took over (a renewal of the
  same shapes, or the next layout's controller in force).

A report is relied on from L after its stamp until the next report's controller is in
force: the next report solved is at most max(I, L) younger (one solve at a time, each
taking the newest report), and its controller comes L after it, so a report is relied on
up to L + max(I, L) old, which S confirms once it happens. A is :data:`MARGIN` times the
larger of max S and that prediction over the last :data:`WINDOW` of each, rounded up to
:data:`QUANTUM_S` (few distinct values, so a recurring layout is
solved once per value: the memo and the store key on it); until a controller went in
force, the stated one. A solver that keeps up with its reports then never sees its
controllers go stale, and the growth is speed x (A + tau + late) with A what this
vessel's solver needs, not a guess: a fast solver gets a small A (less growth), a slow
one a large A instead of stops (and where that growth leaves no winning set, the
synthesis says so).
"""

from __future__ import annotations

import math
from collections import deque

from hil.runtime.settings import NS_PER_S

MARGIN = 1.25
"""Factor over the largest measured age: room for jitter of the reports and the solve."""
QUANTUM_S = 0.25
"""A is a multiple of this (s)."""
WINDOW = 8
"""Supersessions remembered: a slow spell (a silent tracker) leaves A after this many."""


class ReportAgeBudget:
    """The report age (s) each new controller is solved for.

    Args:
        stated_s: The scenario's ``max_report_age_s`` (> 0): A when not measuring, and
            until the first age is measured.
        tracks: Some obstacle moves (a speed bound above zero): decisions may rely on a
            report only while it is at most A old. False: obstacles are fixed between
            layouts, a report never ages, and A (the stated age) grows nothing.
        measured: Derive A from the measured ages (see module docstring); only when
            `tracks`.

    Raises:
        ValueError: A stated age that is not > 0.
    """

    def __init__(self, stated_s: float, tracks: bool = True, measured: bool = False) -> None:
        if not stated_s > 0.0:
            raise ValueError(f"stated report age must be > 0 s, got {stated_s!r}")
        self.stated_s = stated_s
        self.tracks = tracks
        self.measured = measured and tracks
        self._superseded_s: deque[float] = deque(maxlen=WINDOW)
        self._latencies_s: deque[float] = deque(maxlen=WINDOW)
        self._intervals_s: deque[float] = deque(maxlen=WINDOW)
        self._last_report_ns: int | None = None
        self.largest_age_s = 0.0
        """Largest age any relied-on report had when superseded this run (s)."""

    def reported(self, report_t_ns: int) -> None:
        """Note a report taken in (new shapes or a renewal), stamped `report_t_ns`."""
        last = self._last_report_ns
        if last is not None and report_t_ns > last:
            self._intervals_s.append((report_t_ns - last) / NS_PER_S)
        if last is None or report_t_ns > last:
            self._last_report_ns = report_t_ns

    def in_force(self, report_t_ns: int, t_ns: int) -> None:
        """Note that a controller of the report stamped `report_t_ns` went in force at `t_ns`."""
        self._latencies_s.append(max(0.0, (t_ns - report_t_ns) / NS_PER_S))

    def superseded(self, report_t_ns: int, t_ns: int) -> None:
        """Note that the report stamped `report_t_ns` stopped being relied on at `t_ns`."""
        age_s = max(0.0, (t_ns - report_t_ns) / NS_PER_S)
        self._superseded_s.append(age_s)
        self.largest_age_s = max(self.largest_age_s, age_s)

    def next_s(self) -> float:
        """Return A for the next submitted layout (s): stated, or from the measured ages."""
        if not self.measured or not self._latencies_s:
            return self.stated_s
        latency = max(self._latencies_s)
        predicted = latency + max(latency, max(self._intervals_s, default=0.0))
        need = MARGIN * max(predicted, max(self._superseded_s, default=0.0))
        steps = math.ceil(need / QUANTUM_S - 1e-9)  # 1e-9: no extra step for an ulp
        return max(1, steps) * QUANTUM_S
