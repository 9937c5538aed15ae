"""Named pose feeds: the motion-capture feeds the guarantee's premises are measured for.

The estimation bound (the scenario's ``estimation_position_m`` / ``estimation_heading_rad``)
holds for the pose feed it was measured with, and only for it: its rate, its delay, and
whether each pose is stamped when the camera captured it or when a driver received it.
The lab has two:

- ``qtm-100hz``: Qualisys QTM's real-time stream read directly (:mod:`hil.adapters.qtm`),
  every camera frame at 100 Hz, stamped with QTM's own capture time, delivered about
  10 ms later. The scenario's ``[transient]`` table was measured with it.
- ``ros-10hz-receive-stamped``: the mocap4ros2_qualisys driver (public HEAD, Jan 2024):
  it polls ``GetCurrentFrame`` on a 100-ms wall timer (10 Hz) and stamps each pose when
  it receives it, so the stamp hides the pose's age. QTM answers with its newest frame,
  so that age is about one camera period (10 ms) plus QTM's processing and the TCP round
  trip: 20 ms is taken as the hidden delay. Measured with the shipped EKF (its 1-mm pose
  model): 20 ms gives the bound of ``[pose_feeds.ros-10hz-receive-stamped]``; at 30 ms and
  more (the whole timer period, 0.11 s, included) the filter's gate refuses the late
  poses and the estimate diverges: no bound exists there without retuning the filter.

A scenario ships the bound per feed (``[transient]`` for ``qtm-100hz``,
``[pose_feeds.NAME]`` for the others); a vessel config's ``pose_feed`` says which is in
force, and ``hil vessel`` judges the feed it measures against that feed's premise.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["DEFAULT_POSE_FEED", "POSE_FEEDS", "PoseFeed", "pose_feed"]


@dataclass(frozen=True, slots=True)
class PoseFeed:
    """A pose feed as the guarantee's premise states it.

    Attributes:
        name: The profile's name (a vessel config's ``pose_feed``).
        rate_hz: Poses per second the bound was measured with (Hz), > 0.
        stamped_at_capture: Whether each pose carries its capture time (else the time a
            driver received it).
        delay_s: Capture to delivery (s): with capture stamps the EKF compensates it;
            stamped on receipt it is the stamp's hidden error (the worst the feed allows).
        rate_tolerance: Allowed relative shortfall or excess of a measured rate.
        latency_min_ms: Least median stamp-to-arrival latency a check accepts (ms): with
            capture stamps, below it the poses look stamped on receipt.
        latency_max_ms: Largest median stamp-to-arrival latency a check accepts (ms).
        description: One line on where the feed comes from.
    """

    name: str
    rate_hz: float
    stamped_at_capture: bool
    delay_s: float
    rate_tolerance: float
    latency_min_ms: float
    latency_max_ms: float
    description: str

    def premise_text(self) -> str:
        """Return the premise in words: rate and stamping."""
        stamps = "stamped at capture" if self.stamped_at_capture else \
            f"stamped on receipt (hidden delay up to {1e3 * self.delay_s:g} ms)"
        return f"{self.rate_hz:g} Hz, {stamps}"


DEFAULT_POSE_FEED = "qtm-100hz"
"""The feed a scenario's ``[transient]`` estimation bound is measured with."""

POSE_FEEDS: dict[str, PoseFeed] = {
    feed.name: feed
    for feed in (
        PoseFeed(DEFAULT_POSE_FEED, 100.0, True, 0.01, 0.1, 2.0, 25.0,
                 "Qualisys QTM read directly (hil's qtm backend, or a driver that keeps "
                 "QTM's capture stamps): every camera frame, ~10 ms to hil"),
        PoseFeed("ros-10hz-receive-stamped", 10.0, False, 0.02, 0.1, 0.0, 25.0,
                 "mocap4ros2_qualisys: GetCurrentFrame polled every 100 ms, each pose "
                 "stamped on receipt"),
    )
}
"""Every named pose feed, by name."""


def pose_feed(name: str) -> PoseFeed:
    """Return the named pose feed.

    Raises:
        KeyError: No feed has that name (the message lists the names).
    """
    try:
        return POSE_FEEDS[name]
    except KeyError:
        raise KeyError(f"unknown pose feed {name!r}; known: "
                       f"{', '.join(sorted(POSE_FEEDS))}") from None
