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
