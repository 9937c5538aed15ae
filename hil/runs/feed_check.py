"""The preflight's judgement of a sensor feed against the premises of the guarantee.

`hil vessel --check` listens to the vessel's topics for a few seconds and records, per
message, when it arrived and what it carried (:class:`FeedSeries`). The functions here
turn those series into figures (:func:`feed_figures`) and lines of PASS or FAIL
(:func:`judge_pose_feed`, :func:`judge_imu_feed`, :func:`judge_publishers`,
:func:`judge_position`): pure functions over arrays, tested without DDS.

The premises: the EKF's estimation bound (the scenario's ``estimation_position_m``) was
measured on the pose feed in force (the vessel config's ``pose_feed``,
:mod:`hil.core.pose_feeds`): by default 100 Hz stamped at capture and delivered about
10 ms later; ``ros-10hz-receive-stamped`` is 10 Hz stamped on receipt (latency near zero:
the stamp hides the delay), with its own, wider bound. A feed slower than the premise
in force fails, naming the key to change.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from hil.adapters.feed_tape import Heard
from hil.core.arrays import BoolArray, IntArray
from hil.core.clock import NS_PER_S
from hil.core.pose_feeds import DEFAULT_POSE_FEED, POSE_FEEDS, PoseFeed
from hil.runs.feed_premise import rate_refusal

__all__ = [
    "CheckLine",
    "FeedFigures",
    "FeedPremises",
    "FeedSeries",
    "PositionFinding",
    "feed_figures",
    "judge_imu_feed",
    "judge_pose_feed",
    "judge_position",
    "judge_publishers",
    "pose_premises",
    "series_of",
]


@dataclass(frozen=True)
class FeedPremises:
    """What a feed must look like for the estimation bound to hold.

    Attributes:
        rate_hz: Nominal rate (Hz).
        rate_tolerance: Allowed relative deviation of the measured rate.
        latency_min_ms: Smallest median stamp-to-arrival latency (ms); below it the
            samples are stamped on receipt, not at capture.
        latency_max_ms: Largest median stamp-to-arrival latency (ms).
        jitter_max_ms: Largest 99th percentile of |arrival interval - 1 / rate| (ms).
        nan_share_max: Largest share of messages with NaN values (occlusions).
        same_clock_s: Largest |latency| for stamps and arrivals to be on one clock (s).
    """

    rate_hz: float = 100.0
    rate_tolerance: float = 0.1
    latency_min_ms: float = 2.0
    latency_max_ms: float = 25.0
    jitter_max_ms: float = 25.0
    nan_share_max: float = 0.01
    same_clock_s: float = 1.0


POSE_PREMISES = FeedPremises()
"""The pose feed the EKF bound was measured with: 100 Hz, stamped ~10 ms before arrival."""


def pose_premises(feed: PoseFeed) -> FeedPremises:
    """Return what a pose feed must look like for `feed`'s estimation bound to hold."""
    return replace(POSE_PREMISES, rate_hz=feed.rate_hz, rate_tolerance=feed.rate_tolerance,
                   latency_min_ms=feed.latency_min_ms, latency_max_ms=feed.latency_max_ms,
                   jitter_max_ms=max(POSE_PREMISES.jitter_max_ms, 250.0 / feed.rate_hz))
IMU_PREMISES = FeedPremises(rate_hz=100.0, rate_tolerance=0.5, latency_min_ms=0.0,
                            latency_max_ms=50.0, jitter_max_ms=50.0)
"""The IMU feed: at least 50 Hz, fresh; its stamps are not judged for capture."""


@dataclass(frozen=True)
class FeedSeries:
    """What one topic delivered while the preflight listened.

    Attributes:
        topic: The ROS topic.
        arrival_ns: Node-clock time of each message's arrival (ns), shape (N,).
        stamp_ns: Each message's header stamp (ns), shape (N,).
        finite: Whether each message's values were all finite, shape (N,).
        frame_ids: Each message's header.frame_id, length N.
    """

    topic: str
    arrival_ns: IntArray
    stamp_ns: IntArray
    finite: BoolArray
    frame_ids: tuple[str, ...] = field(default=())


def series_of(heard: Heard) -> FeedSeries:
    """Return what a subscription taped (:class:`hil.adapters.feed_tape.Heard`) as arrays."""
    return FeedSeries(heard.topic, np.asarray(heard.arrival_ns, dtype=np.int64),
                      np.asarray(heard.stamp_ns, dtype=np.int64),
                      np.asarray(heard.finite, dtype=np.bool_), heard.frame_ids)


@dataclass(frozen=True)
class FeedFigures:
    """A feed's figures (NaN where too few messages to tell).

    Attributes:
        count: Messages received.
        rate_hz: Messages per second between the first and last arrival (Hz).
        jitter_ms: 99th percentile of |arrival interval - median interval| (ms).
        latency_ms: Median of arrival - stamp (ms).
        latency_p95_ms: 95th percentile of arrival - stamp (ms).
        nan_share: Share of messages with non-finite values.
        frame_ids: The distinct frame ids seen, most frequent first.
    """

    count: int
    rate_hz: float
    jitter_ms: float
    latency_ms: float
    latency_p95_ms: float
    nan_share: float
    frame_ids: tuple[str, ...]


@dataclass(frozen=True)
class CheckLine:
    """One judged line of the preflight.

    Attributes:
        topic: The topic (or "arena") the line is about.
        what: The quantity ("rate", "latency", ...).
        value: What was measured, in words with units.
        premise: What the guarantee assumes, in words.
        ok: Whether the measurement meets the premise.
        fix: What to change when it does not ("" when ok).
    """

    topic: str
    what: str
    value: str
    premise: str
    ok: bool
    fix: str = ""

    def text(self) -> str:
        """Return the line as printed: verdict, topic, quantity, value, premise, fix."""
        line = f"{'PASS' if self.ok else 'FAIL'}  {self.topic}  {self.what}: {self.value} " \
               f"(premise: {self.premise})"
        return line if self.ok or not self.fix else f"{line}: {self.fix}"


def feed_figures(series: FeedSeries) -> FeedFigures:
    """Return the rate, jitter, latency, NaN share and frame ids of a recorded feed."""
    arrival = np.sort(np.asarray(series.arrival_ns, dtype=np.int64))
    count = len(arrival)
    rate = jitter = latency = latency_p95 = float("nan")
    if count >= 2:
        span_s = (arrival[-1] - arrival[0]) / NS_PER_S
        rate = (count - 1) / span_s if span_s > 0 else float("inf")
        intervals_ms = np.diff(arrival) / 1e6
        jitter = float(np.percentile(np.abs(intervals_ms - np.median(intervals_ms)), 99))
    if count:
        lag_ms = (np.asarray(series.arrival_ns, dtype=np.int64)
                  - np.asarray(series.stamp_ns, dtype=np.int64)) / 1e6
        latency = float(np.median(lag_ms))
        latency_p95 = float(np.percentile(lag_ms, 95))
    nan_share = float(1.0 - np.mean(series.finite)) if count else float("nan")
    ids, counts = np.unique(np.asarray(series.frame_ids, dtype=str), return_counts=True)
    frames = tuple(str(ids[i]) for i in np.argsort(-counts, kind="stable"))
    return FeedFigures(count, rate, jitter, latency, latency_p95, nan_share, frames)


def judge_pose_feed(series: FeedSeries, expected_frame: str, sim_time: bool,
                    feed: PoseFeed = POSE_FEEDS[DEFAULT_POSE_FEED]) -> list[CheckLine]:
    """Judge the pose feed: rate, jitter, latency (capture stamps), clock, frame, NaN.

    Args:
        series: What the pose topic delivered.
        expected_frame: The config's ``[ros] pose_frame_id``.
        sim_time: Whether hil follows /clock (``[ros] use_sim_time``).
        feed: The premise in force (the vessel config's ``pose_feed``).
    """
    figures = feed_figures(series)
    lines = _judge_timing(series.topic, figures, sim_time, pose_premises(feed),
                          capture=feed.stamped_at_capture)
    lines = [_pose_fix(line, figures, feed) for line in lines]
    if figures.count:
        seen = ", ".join(repr(f) for f in figures.frame_ids)
        wrong = [f for f in figures.frame_ids if f and f != expected_frame]
        lines.append(CheckLine(series.topic, "frame id", seen, f"{expected_frame!r}", not wrong,
                               f'set [ros] pose_frame_id = "{wrong[0]}" and check '
                               "[ros.transform]" if wrong else ""))
    return lines


def _pose_fix(line: CheckLine, figures: FeedFigures, feed: PoseFeed) -> CheckLine:
    """Name the vessel config's ``pose_feed`` in a failed rate or stamping line."""
    if line.ok:
        return line
    if line.what == "rate" and figures.rate_hz < feed.rate_hz:
        return replace(line, fix=rate_refusal(figures.rate_hz, feed, "the feed"))
    if line.what == "latency" and figures.latency_ms < feed.latency_min_ms:
        return replace(line, fix=f"{line.fix}, or set pose_feed = \"ros-10hz-receive-stamped\" "
                       "(a premise for poses stamped on receipt)")
    return line


def judge_imu_feed(series: FeedSeries, sim_time: bool,
                   premises: FeedPremises = IMU_PREMISES) -> list[CheckLine]:
    """Judge the IMU feed: rate, jitter, latency, clock and NaN share."""
    return _judge_timing(series.topic, feed_figures(series), sim_time, premises, capture=False)


def _judge_timing(topic: str, f: FeedFigures, sim_time: bool, p: FeedPremises,
                  capture: bool) -> list[CheckLine]:
    """Judge what every feed shares: arrivals, rate, jitter, clock, latency, NaN share."""
    if f.count < 2:
        return [CheckLine(topic, "messages", f"{f.count} received", f"{p.rate_hz:g} Hz", False,
                          "nothing to judge: check the publisher runs (ros2 topic hz "
                          f"{topic}) and the QoS line")]
    low, high = p.rate_hz * (1 - p.rate_tolerance), p.rate_hz * (1 + p.rate_tolerance)
    clock = "/clock (sim time)" if sim_time else "wall time"
    same_clock = abs(f.latency_ms) <= p.same_clock_s * 1e3
    lines = [
        CheckLine(topic, "rate", f"{f.rate_hz:.1f} Hz ({f.count} messages)",
                  f"{low:g}-{high:g} Hz", low <= f.rate_hz <= high,
                  f"publish at {p.rate_hz:g} Hz: the estimation bound was measured at that rate"),
        CheckLine(topic, "jitter", f"{f.jitter_ms:.2f} ms (p99)", f"<= {p.jitter_max_ms:g} ms",
                  f.jitter_ms <= p.jitter_max_ms,
                  "check the publisher's load and the network between it and hil"),
        CheckLine(topic, "time source", f"stamps {f.latency_ms / 1e3:+.3g} s from hil's {clock}",
                  f"one clock (within {p.same_clock_s:g} s)", same_clock,
                  "set [ros] use_sim_time to the publisher's clock, or synchronize the "
                  "clocks (chrony)"),
    ]
    if same_clock:
        receipt = capture and f.latency_ms < p.latency_min_ms
        lines.append(CheckLine(
            topic, "latency",
            f"{f.latency_ms:.1f} ms median, {f.latency_p95_ms:.1f} ms p95 stamp to arrival"
            + (" (stamped on receipt?)" if receipt else ""),
            f"{p.latency_min_ms:g}-{p.latency_max_ms:g} ms"
            + (", stamped at capture" if capture else ""),
            p.latency_min_ms <= f.latency_ms <= p.latency_max_ms,
            "stamp each sample at capture (the mocap's frame time), not on receipt"
            if receipt else "reduce the delay between capture and hil (network, driver)"))
    lines.append(CheckLine(topic, "NaN share", f"{100 * f.nan_share:.1f} %",
                           f"<= {100 * p.nan_share_max:g} %", f.nan_share <= p.nan_share_max,
                           "check the sensor sees the vessel (mocap: the rigid body occluded "
                           "or not tracked)"))
    return lines


def judge_publishers(topic: str, reliabilities: Sequence[str], best_effort: bool,
                     qos_refusals: int) -> CheckLine:
    """Judge who publishes `topic`: at least one, with QoS the subscription matches.

    Args:
        topic: The topic.
        reliabilities: Each publisher's reliability (``"RELIABLE"``, ``"BEST_EFFORT"``).
        best_effort: Whether hil subscribes best effort (``[ros] best_effort_sensors``).
        qos_refusals: Incompatible-QoS events the subscription received.
    """
    ours = "BEST_EFFORT" if best_effort else "RELIABLE"
    seen = ", ".join(reliabilities) if reliabilities else "no publisher"
    value = f"{len(reliabilities)} publisher(s): {seen}; hil subscribes {ours}"
    mismatched = not best_effort and "BEST_EFFORT" in reliabilities
    if mismatched or qos_refusals:
        return CheckLine(topic, "QoS", value + f" ({qos_refusals} incompatible-QoS events)",
                         "publishers hil's subscription can match", False,
                         "set [ros] best_effort_sensors = true" if mismatched else
                         "match the publisher's QoS (ros2 topic info -v " + topic + ")")
    return CheckLine(topic, "QoS", value, "at least one publisher hil can match",
                     bool(reliabilities), "" if reliabilities else
                     f"start the driver, or check the topic name and ROS_DOMAIN_ID ({topic})")


@dataclass(frozen=True)
class PositionFinding:
    """Where the last pose puts the vessel, for :func:`judge_position`.

    Attributes:
        pose: Arena pose (x m, y m, yaw rad), or None when no pose could be used.
        inside: Whether (x, y) lies inside the arena.
        cell: The controller's flat cell index (-1 outside the grid).
        value: Steps to the target from the cell at rest (inf: not winning).
    """

    pose: tuple[float, float, float] | None
    inside: bool
    cell: int
    value: float


def judge_position(finding: PositionFinding, scenario: str) -> list[CheckLine]:
    """Judge the vessel's pose in the arena: inside, on a cell, and winning at rest."""
    if finding.pose is None:
        return [CheckLine("arena", "pose", "no usable pose", "a pose inside the arena", False,
                          "fix the pose lines above")]
    x, y, yaw = finding.pose
    where = f"({x:+.2f} m, {y:+.2f} m, {np.degrees(yaw):+.0f} deg)"
    winning = bool(np.isfinite(finding.value))
    return [
        CheckLine("arena", "pose", where, f"inside the arena of scenario {scenario!r}",
                  finding.inside, "move the vessel into the arena, or check [ros.transform]"),
        CheckLine("arena", "cell", str(finding.cell) if finding.cell >= 0 else "outside the grid",
                  "a cell of the grid", finding.cell >= 0, "check [ros.transform]"),
        CheckLine("arena", "winning",
                  f"value {finding.value:g} steps at rest" if winning else "not winning",
                  "in the winning set (docking guaranteed from here)", winning,
                  "move the vessel to a winning start (hil plot shows the winning set)"),
    ]
