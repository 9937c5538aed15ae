"""The pose feed against the premise in force: refuse a feed slower than the bound assumes.

The estimation bound a vessel config puts in force (``pose_feed``, :mod:`hil.core.pose_feeds`)
was measured at that feed's rate and stamping. `hil vessel` refuses to claim the guarantee
on a slower feed: a ``[qtm] rate_hz`` below the premise is refused when the config is read
(:func:`qtm_rate_refusal`), and the rate a feed delivers is measured on the run's clock over
the first second after its first pose (:func:`measure_rate`) and refused when even the
fastest rate its count allows is below the premise's tolerance (:func:`rate_refusal`).
Each message names the key to change.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

from hil.adapters.qtm import QtmConfig
from hil.core.pose_feeds import POSE_FEEDS, PoseFeed

__all__ = ["RateWindow", "measure_rate", "qtm_rate_refusal", "rate_refusal", "slowest_rate_hz"]


def slowest_rate_hz(feed: PoseFeed) -> float:
    """Return the slowest rate (Hz) that `feed`'s premise accepts (its tolerance below)."""
    return feed.rate_hz * (1.0 - feed.rate_tolerance)


def _covering(rate_hz: float, stamped_at_capture: bool) -> str:
    """Return the advice naming a feed whose premise covers this one, or ""."""
    fits = [f for f in POSE_FEEDS.values() if rate_hz >= slowest_rate_hz(f)
            and (stamped_at_capture or not f.stamped_at_capture)]
    if not fits:
        return ""
    best = max(fits, key=lambda f: f.rate_hz)
    return f', or set pose_feed = "{best.name}" to run with its wider bound ({best.premise_text()})'


def rate_refusal(rate_hz: float, feed: PoseFeed, what: str,
                 fastest_hz: float | None = None) -> str:
    """Return why a pose feed at `rate_hz` (Hz) breaks `feed`'s premise, or "" if it does not.

    Args:
        rate_hz: The measured (or configured) rate of the feed (Hz).
        feed: The premise in force.
        what: The feed in words ("the pose topic /voyager/...", "QTM").
        fastest_hz: The fastest rate the measurement allows (:attr:`RateWindow.fastest_hz`),
            judged instead of `rate_hz`; None: `rate_hz` is exact (a configured rate).
    """
    if (rate_hz if fastest_hz is None else fastest_hz) >= slowest_rate_hz(feed):
        return ""
    return (f"{what} delivers {rate_hz:.1f} Hz, slower than the premise in force "
            f'(pose_feed = "{feed.name}": {feed.premise_text()}; at least '
            f"{slowest_rate_hz(feed):g} Hz): the guarantee's estimation bound does not hold "
            f"on it; speed the feed up{_covering(rate_hz, feed.stamped_at_capture)}")


def qtm_rate_refusal(qtm: QtmConfig, feed: PoseFeed) -> str:
    """Return why ``[qtm] rate_hz`` breaks `feed`'s premise, or "" (None: every frame)."""
    if qtm.rate_hz is None or qtm.rate_hz >= slowest_rate_hz(feed):
        return ""
    return (f"key qtm.'rate_hz' = {qtm.rate_hz} is slower than the premise in force "
            f'(pose_feed = "{feed.name}": {feed.premise_text()}): set [qtm] rate_hz to at '
            f"least {feed.rate_hz:g} (or remove it for every camera frame)"
            f"{_covering(float(qtm.rate_hz), True)}")


@dataclass(frozen=True)
class RateWindow:
    """Poses counted over a window of the run's clock.

    Attributes:
        poses: Poses that arrived in the window.
        seconds: How long the window lasted on the run's clock (s); under a simulated
            clock that stood still (a lockstep simulator waiting for commands) about 0.
    """

    poses: int
    seconds: float

    @property
    def measured(self) -> bool:
        """Whether the run's clock moved enough to tell a rate (half the window asked)."""
        return self.seconds > 0.0

    @property
    def rate_hz(self) -> float:
        """Return poses per second of the run's clock (0 where not :attr:`measured`)."""
        return self.poses / self.seconds if self.measured else 0.0

    @property
    def fastest_hz(self) -> float:
        """Return the fastest rate consistent with the count (Hz).

        n arrivals in a window of D seconds allow a period as short as D / (n + 1), not
        shorter: a 10-Hz feed counted over 1.0x s may show 9 poses. The refusal judges
        this, so a feed exactly at the premise's tolerance is never refused by the window's
        phase.
        """
        return (self.poses + 1) / self.seconds if self.measured else math.inf


def measure_rate(count: Callable[[], int], seconds: float,
                 now_ns: Callable[[], int] = time.monotonic_ns,
                 sleep: Callable[[float], None] = time.sleep) -> RateWindow:
    """Count how many poses `count` (poses so far) gains over `seconds` of wall time.

    The window's length is read on `now_ns` (the run's clock: simulated time under
    ``use_sim_time``). A window in which that clock advanced less than half of `seconds`
    is not measured (:attr:`RateWindow.measured` false): the clock stood still.
    """
    before, start = count(), now_ns()
    sleep(seconds)
    span_s = (now_ns() - start) / 1e9
    return RateWindow(count() - before, span_s if span_s >= 0.5 * seconds else 0.0)
