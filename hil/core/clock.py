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


class WallAnchor:
    """Simulated time held to a wall clock: it sleeps when ahead and slips when far off.

    Simulated time t is due on the wall at ``wall_at_anchor + (t - t_at_anchor) / speed``.
    When the wall clock is more than `slip_ns` from that (the process was starved, or the
    system clock was set), the map is anchored anew at the present: the samples' stamps
    show a gap. Catching up instead would crowd many simulated periods into a burst, and
    keeping the lag would read as sensor latency to whoever compares stamps with its own
    clock.

    Args:
        wall_ns: The wall clock (ns), e.g. :func:`time.time_ns` (the ROS system clock:
            stamps a receiver compares with its own) or :func:`time.monotonic_ns`.
        t_ns: Simulated time at the first anchor (ns), made when the map is first used.
        speed: Simulated seconds per wall second, > 0.
        slip_ns: How far off the wall clock may be before the map is anchored anew (ns).
        sleep: The sleep function (seconds); injectable for tests.
    """

    def __init__(self, wall_ns: Callable[[], int], t_ns: int, speed: float = 1.0,
                 slip_ns: int = 20_000_000, sleep: Callable[[float], None] = time.sleep) -> None:
        if not speed > 0:
            raise ValueError(f"speed must be positive, got {speed!r}")
        if slip_ns <= 0:
            raise ValueError(f"slip_ns must be positive, got {slip_ns!r}")
        self._wall_ns = wall_ns
        self._speed = float(speed)
        self._slip_ns = int(slip_ns)
        self._sleep = sleep
        self.slips = 0
        """How many times the map was anchored anew after the first."""
        self.slipped_ns = 0
        """The wall time the slips skipped (ns; a clock set back counts negative)."""
        self._t_anchor_ns = int(t_ns)
        self._wall_anchor_ns: int | None = None

    def _anchor(self, t_ns: int) -> None:
        self._t_anchor_ns = int(t_ns)
        self._wall_anchor_ns = int(self._wall_ns())

    def wall_of(self, t_ns: int) -> int:
        """Return the wall time (ns) at which simulated time `t_ns` is due on the present map.

        The first call anchors the map (a slow first step, e.g. a compilation, is no slip).
        """
        if self._wall_anchor_ns is None:
            self._wall_anchor_ns = int(self._wall_ns())
        return self._wall_anchor_ns + round((t_ns - self._t_anchor_ns) / self._speed)

    def wait_for(self, t_ns: int) -> None:
        """Sleep until simulated time `t_ns` is due; anchor anew if the wall is `slip_ns` off.

        Behind by less than `slip_ns`, it returns at once (the next periods catch up).
        """
        ahead_ns = self.wall_of(t_ns) - self._wall_ns()
        if abs(ahead_ns) > self._slip_ns:
            self.slips += 1
            self.slipped_ns -= ahead_ns
            self._anchor(t_ns)
        elif ahead_ns > 0:
            self._sleep(ahead_ns / NS_PER_S)
