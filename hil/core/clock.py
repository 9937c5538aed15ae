"""Clocks: simulated time for sim and replay, wall time on the vessel.

Both satisfy :class:`hil.adapters.interfaces.Clock`. The simulated clock moves
only when the loop sleeps, and then advances the simulated world with it, so a
3-minute docking run takes seconds and repeats exactly for a given seed.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

NS_PER_S = 1_000_000_000
"""Nanoseconds per second: every hil time stamp is integer nanoseconds."""


def stamp_fields(t_ns: int) -> tuple[int, int]:
    """Return a time (ns) as a ROS stamp's (sec, nanosec): whole seconds and the rest."""
    sec, nanosec = divmod(int(t_ns), NS_PER_S)
    return sec, nanosec


def stamp_to_ns(stamp: Any) -> int:
    """Return a builtin_interfaces/Time (rclpy's, rosbags': ``sec``, ``nanosec``) in ns."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def fill_stamp(stamp: Any, t_ns: int) -> None:
    """Write a time (ns) into a builtin_interfaces/Time in place (:func:`stamp_fields`)."""
    stamp.sec, stamp.nanosec = stamp_fields(t_ns)


class SimClock:
    """Simulated time that advances the world when the loop sleeps.

    Args:
        start_ns: Initial time (ns).
        advance: Called as `advance(t_from_ns, t_to_ns)` whenever time moves
            forward, e.g. to integrate the vessel; None for a bare clock.
        stalls_ns: Spans [start, stop) (ns) in which the sleeper cannot run (a stalled
            loop: a pause of the process, a busy CPU): a sleep ending inside one ends at
            its stop, the world moving on meanwhile (fault injection).
    """

    def __init__(
        self,
        start_ns: int = 0,
        advance: Callable[[int, int], None] | None = None,
        stalls_ns: tuple[tuple[int, int], ...] = (),
    ) -> None:
        self._now_ns = int(start_ns)
        self._advance = advance
        self._stalls_ns = stalls_ns

    def now_ns(self) -> int:
        """Return the simulated time (ns)."""
        return self._now_ns

    def sleep_until(self, t_ns: int) -> None:
        """Advance simulated time (and the world) to `t_ns`; never moves backwards."""
        if t_ns <= self._now_ns:
            return
        for start, stop in self._stalls_ns:
            if start <= t_ns < stop:
                t_ns = stop
        if self._advance is not None:
            self._advance(self._now_ns, t_ns)
        self._now_ns = int(t_ns)


class WallClock:
    """Monotonic wall time, counted from the clock's creation.

    Args:
        sleep: The sleep function (seconds); injectable for tests.
    """

    def __init__(self, sleep: Callable[[float], None] = time.sleep) -> None:
        self._origin_ns = time.monotonic_ns()
        self._sleep = sleep

    def now_ns(self) -> int:
        """Return nanoseconds since the clock was created."""
        return time.monotonic_ns() - self._origin_ns

    def sleep_until(self, t_ns: int) -> None:
        """Sleep until `t_ns`; return at once if it has passed (an overrun)."""
        remaining_ns = t_ns - self.now_ns()
        if remaining_ns > 0:
            self._sleep(remaining_ns * 1e-9)


# Steady-clock time (ns) within which a bracketed read is taken as one instant, so that
# :func:`read_beside` tries no more.
_TIGHT_READ_NS = 100_000


def read_beside(clock: Callable[[], int], steady: Callable[[], int],
                tries: int = 3) -> tuple[int, int, int]:
    """Read `clock` between two reads of `steady`; return (clock, steady's midpoint, span) (ns).

    A thread held between the reads would pair the two clocks wrongly by the hold: the
    tightest of up to `tries` bracketed reads is kept (the first within 0.1 ms ends it), and
    its span (the steady time between its two reads) bounds the pairing's error.
    """
    best: tuple[int, int, int] | None = None
    for _ in range(max(1, tries)):
        before = int(steady())
        reading = int(clock())
        after = int(steady())
        if best is None or after - before < best[2]:
            best = (reading, (before + after) // 2, after - before)
        if best[2] <= _TIGHT_READ_NS:
            break
    assert best is not None
    return best


class WallAnchor:
    """Simulated time held to the wall, and the system clock's reading when each time is due.

    Simulated time t is due at ``steady_at_anchor + (t - t_at_anchor) / speed`` on a steady
    clock (monotonic: never set). :meth:`wait_for` sleeps when ahead; a little behind (a
    busy CPU), it returns at once so the next periods catch up; more than `slip_ns` behind
    (a paused process or machine), it anchors the map anew at the present, a gap in the
    simulated stream rather than a burst of it.

    :meth:`system_of` is what a sensor stamping at capture would write: the steady due
    time plus the system clock's present offset from the steady clock. A step of the
    system clock (NTP setting it, a virtual machine catching up after a pause) thus moves
    the stamps at once, as it moves the clock of whoever receives them; stamps from the
    first anchor on would read as that much sensor latency.

    Args:
        t_ns: Simulated time at the first anchor (ns); the map is anchored when first
            used, so a slow first step (a compilation) is no slip.
        speed: Simulated seconds per wall second, > 0.
        slip_ns: How far behind the wall may be before the map is anchored anew (ns).
        steady: The steady clock (ns).
        system: The system clock (ns; the ROS clock on wall time).
        sleep: The sleep function (seconds); injectable for tests.
    """

    def __init__(self, t_ns: int, speed: float = 1.0, slip_ns: int = 500_000_000,
                 steady: Callable[[], int] = time.monotonic_ns,
                 system: Callable[[], int] = time.time_ns,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        if not speed > 0:
            raise ValueError(f"speed must be positive, got {speed!r}")
        if slip_ns <= 0:
            raise ValueError(f"slip_ns must be positive, got {slip_ns!r}")
        self._steady = steady
        self._system = system
        self._speed = float(speed)
        self._slip_ns = int(slip_ns)
        self._sleep = sleep
        self.slips = 0
        """How many times the map was anchored anew, the wall too far ahead."""
        self.slipped_ns = 0
        """The wall time the slips skipped (ns)."""
        self._t_anchor_ns = int(t_ns)
        self._steady_anchor_ns: int | None = None

    def _steady_of(self, t_ns: int) -> int:
        if self._steady_anchor_ns is None:
            self._steady_anchor_ns = int(self._steady())
        return self._steady_anchor_ns + round((t_ns - self._t_anchor_ns) / self._speed)

    def system_of(self, t_ns: int) -> int:
        """Return the system clock's reading (ns) when simulated time `t_ns` is due."""
        system, steady, _ = read_beside(self._system, self._steady)
        return self._steady_of(t_ns) + system - steady

    def wait_for(self, t_ns: int) -> None:
        """Sleep until simulated time `t_ns` is due; anchor anew if `slip_ns` behind."""
        ahead_ns = self._steady_of(t_ns) - int(self._steady())
        if ahead_ns > 0:
            self._sleep(ahead_ns / NS_PER_S)
        elif -ahead_ns > self._slip_ns:
            self.slips += 1
            self.slipped_ns -= ahead_ns
            self._t_anchor_ns = int(t_ns)
            self._steady_anchor_ns = int(self._steady())
