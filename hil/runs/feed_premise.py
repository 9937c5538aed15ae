"""The pose feed against the premise in force: refuse a feed slower than the bound assumes.

The estimation bound a vessel config puts in force (``pose_feed``, :mod:`hil.core.pose_feeds`)
was measured at that feed's rate and stamping. `hil vessel` refuses to claim the guarantee
on a slower feed: a ``[qtm] rate_hz`` below the premise is refused when the config is read
(:func:`qtm_rate_refusal`), and the rate a feed delivers is measured over the first second
after its first pose (:func:`measured_rate_hz`) and refused when below the premise's
tolerance (:func:`rate_refusal`). Each message names the key to change.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from hil.adapters.qtm import QtmConfig
from hil.core.pose_feeds import POSE_FEEDS, PoseFeed

__all__ = ["measured_rate_hz", "qtm_rate_refusal", "rate_refusal", "slowest_rate_hz"]


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


def rate_refusal(rate_hz: float, feed: PoseFeed, what: str) -> str:
    """Return why a pose feed at `rate_hz` (Hz) breaks `feed`'s premise, or "" if it does not.

    Args:
        rate_hz: The measured (or configured) rate of the feed (Hz).
        feed: The premise in force.
        what: The feed in words ("the pose topic /voyager/...", "QTM").
    """
    if rate_hz >= slowest_rate_hz(feed):
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


def measured_rate_hz(count: Callable[[], int], seconds: float,
                     sleep: Callable[[float], None] = time.sleep) -> float:
    """Return the rate (Hz) at which `count` (samples so far) grows over `seconds` (> 0)."""
    before = count()
    start = time.monotonic()
    sleep(seconds)
    return (count() - before) / max(time.monotonic() - start, 1e-9)
