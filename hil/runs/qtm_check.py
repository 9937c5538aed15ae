"""`hil vessel --check` with a ``[qtm]`` table: the QTM pose feed against the premise in force.

The preflight reads QTM as a run would (:class:`hil.adapters.qtm.QtmPoseSource`) for the
listening window, polling every few milliseconds, and judges what came: the rate of poses
(against the premise of the vessel config's ``pose_feed``), their latency (when each
pose was taken from the source against its stamp: QTM's capture time mapped onto hil's
clock, the mapping's offset being the fastest frame's delay, so this is the delay beyond
the fastest frame plus the poll), frames QTM numbered but never sent (drops) and frames
with the body lost.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from hil.adapters.interfaces import Clock
from hil.adapters.qtm import QtmConfig, QtmPoseSource
from hil.adapters.qtm_feed import QtmCounters
from hil.core.arrays import FloatArray
from hil.core.pose_feeds import PoseFeed
from hil.core.samples import PoseSample
from hil.runs.feed_check import CheckLine
from hil.runs.feed_premise import qtm_rate_refusal, rate_refusal, slowest_rate_hz

__all__ = ["POLL_S", "QtmWindow", "judge_qtm_feed", "listen_qtm"]

POLL_S = 0.002
"""Seconds between two polls of the source while listening."""

MAX_LOST_SHARE = 0.01
"""Largest share of frames dropped, or with the body lost, the premise allows."""


@dataclass(frozen=True)
class QtmWindow:
    """What the QTM source delivered in the preflight's window.

    Attributes:
        before: The source's counters when the window opened.
        after: Its counters when it closed.
        listened_s: The window's length (s).
        lag_ms: Per pose, the time it was taken from the source minus its stamp (ms), (N,).
        last: The newest pose (arena frame), or None.
    """

    before: QtmCounters
    after: QtmCounters
    listened_s: float
    lag_ms: FloatArray
    last: PoseSample | None


def listen_qtm(source: QtmPoseSource, clock: Clock, seconds: float) -> QtmWindow:
    """Poll `source` (on `clock`) for `seconds` (s) of wall time; return what it delivered."""
    source.poll()  # what came before the window (while the controller was solved)
    before = source.counters
    start_s = time.monotonic()
    lags: list[float] = []
    last: PoseSample | None = None
    while time.monotonic() - start_s < seconds:
        poses = source.poll()
        now_ns = clock.now_ns()
        lags += [(now_ns - p.t_ns) / 1e6 for p in poses]
        last = poses[-1] if poses else last
        time.sleep(POLL_S)
    listened_s = time.monotonic() - start_s
    return QtmWindow(before, source.counters, listened_s, np.asarray(lags, dtype=np.float64),
                     last)


def judge_qtm_feed(window: QtmWindow, config: QtmConfig, feed: PoseFeed) -> list[CheckLine]:
    """Judge the QTM feed: rate, latency, drops and lost body against `feed`'s premise."""
    where = f"qtm {config.host}:{config.port} body {config.body!r}"
    poses = window.after.poses - window.before.poses
    frames = window.after.frames - window.before.frames
    drops = window.after.drops - window.before.drops
    lost = window.after.lost - window.before.lost
    rate = poses / window.listened_s if window.listened_s > 0 else 0.0
    if poses < 2:
        return [CheckLine(where, "poses", f"{poses} received", feed.premise_text(), False,
                          "is QTM streaming, with that body? (hil vessel prints what the "
                          "feed delivered while it waits)")]
    refusal = rate_refusal(rate, feed, "QTM") or qtm_rate_refusal(config, feed)
    lag = float(np.median(window.lag_ms))
    drop_share = drops / max(frames + drops, 1)
    lost_share = lost / max(frames, 1)
    return [
        CheckLine(where, "rate", f"{rate:.1f} Hz ({poses} poses, {frames} frames)",
                  f"at least {slowest_rate_hz(feed):g} Hz", not refusal, refusal),
        CheckLine(where, "latency",
                  f"{lag:.1f} ms median, {float(np.percentile(window.lag_ms, 95)):.1f} ms p95 "
                  "stamp to hil beyond the fastest frame (stamps: QTM's capture time)",
                  f"<= {feed.latency_max_ms:g} ms", lag <= feed.latency_max_ms,
                  "reduce the load on hil's computer and the network between it and QTM"),
        CheckLine(where, "drops", f"{drops} frames never received ({100 * drop_share:.1f} %; "
                  f"QTM's own 6D drop rate {window.after.last_drop_rate})",
                  f"<= {100 * MAX_LOST_SHARE:g} %", drop_share <= MAX_LOST_SHARE,
                  "check the network between QTM and hil (a wired link)"),
        CheckLine(where, "body lost", f"{lost} of {frames} frames ({100 * lost_share:.1f} %)",
                  f"<= {100 * MAX_LOST_SHARE:g} %", lost_share <= MAX_LOST_SHARE,
                  "check the cameras see the vessel's markers (rigid body tracked in QTM)"),
    ]
