"""Why samples on a ROS topic were refused: counted by reason, each with its fix in words.

A feed that "does not arrive" is usually a feed that arrives and is refused (a frame id
the config does not expect, NaN while the mocap body is occluded, stamps on another
clock) or never delivered (a publisher offering QoS the subscription cannot match).
:class:`FeedMonitor` counts every message of one topic and every refusal by
:class:`RejectReason`, so the waiting message, the status line, the run's events and the
summary can say what was received and what to change. Pure Python: the checks read
message attributes, so they serve rclpy messages and test doubles alike.
"""

from __future__ import annotations

import enum
import math
import threading
from dataclasses import dataclass
from typing import Any

from hil.core.clock import NS_PER_S

# A quaternion this far from unit length is not an orientation (the same tolerance as
# hil.adapters.frames.yaw_from_quaternion).
_UNIT_TOLERANCE = 1e-3


class RejectReason(enum.Enum):
    """Closed set of reasons a sample on a sensor topic is refused."""

    FRAME_ID = "frame id"
    NOT_FINITE = "NaN or occluded"
    BAD_QUATERNION = "bad quaternion"
    STALE = "stale"
    OUT_OF_ORDER = "out of order"
    QOS_INCOMPATIBLE = "QoS incompatible"


@dataclass(frozen=True, slots=True)
class Refusal:
    """One refused sample: why, what was seen, and what to change.

    Attributes:
        reason: The kind of refusal.
        detail: What was seen (e.g. ``frame_id 'map' (expected 'world_ned')``).
        fix: The change that makes the feed acceptable, in words.
    """

    reason: RejectReason
    detail: str
    fix: str


@dataclass(frozen=True, slots=True)
class Rejection:
    """The refusals of one reason on one topic so far.

    Attributes:
        reason: The kind of refusal.
        count: Samples refused for it (for QoS: incompatible publishers seen by DDS).
        detail: What the latest one showed.
        fix: What to change, in words.
    """

    reason: RejectReason
    count: int
    detail: str
    fix: str

    def text(self) -> str:
        """Return ``"<count> <detail>: <fix>"``."""
        return f"{self.count} {self.detail}: {self.fix}"


@dataclass(frozen=True, slots=True)
class FeedHealth:
    """A snapshot of one topic's traffic and refusals.

    Attributes:
        topic: The ROS topic.
        noun: What one sample is called, plural (``"poses"``, ``"IMU samples"``).
        received: Messages delivered to the subscription.
        accepted: Messages turned into samples.
        rejections: Refusals by reason, in :class:`RejectReason` order.
        last_ns: Stamp of the newest sample accepted (ns); None: none yet.
    """

    topic: str
    noun: str
    received: int
    accepted: int
    rejections: tuple[Rejection, ...]
    last_ns: int | None = None

    @property
    def rejected(self) -> int:
        """Messages refused (QoS refusals are not messages: not counted)."""
        return sum(r.count for r in self.rejections
                   if r.reason is not RejectReason.QOS_INCOMPATIBLE)

    def describe(self) -> str:
        """Return what was received on the topic and, for each refusal, its fix.

        E.g. ``12 poses received, all rejected: 12 frame_id 'map' (expected
        'world_ned'): set [ros] pose_frame_id = "map"``.
        """
        if self.received == 0:
            head = f"no {self.noun} received"
        elif self.accepted == 0:
            head = f"{self.received} {self.noun} received, all rejected"
        else:
            head = f"{self.received} {self.noun} received, {self.rejected} rejected"
        if not self.rejections:
            return head
        return f"{head}: " + "; ".join(r.text() for r in self.rejections)


class FeedMonitor:
    """Thread-safe counters of one topic: messages received, accepted, refused by reason.

    Args:
        topic: The ROS topic.
        noun: What one sample is called, plural.
    """

    def __init__(self, topic: str, noun: str) -> None:
        self.topic = topic
        self.noun = noun
        self._lock = threading.Lock()
        self._received = 0
        self._accepted = 0
        self._last_ns: int | None = None
        self._counts: dict[RejectReason, int] = {}
        self._latest: dict[RejectReason, Refusal] = {}

    def received(self) -> None:
        """Count one message delivered to the subscription."""
        with self._lock:
            self._received += 1

    def accepted(self, stamp_ns: int) -> None:
        """Count one message turned into a sample stamped `stamp_ns` (ns)."""
        with self._lock:
            self._accepted += 1
            self._last_ns = stamp_ns if self._last_ns is None else max(self._last_ns, stamp_ns)

    def refused(self, refusal: Refusal, count: int | None = None) -> None:
        """Count one refusal, or set its total to `count` (DDS keeps the QoS totals)."""
        with self._lock:
            done = self._counts.get(refusal.reason, 0)
            self._counts[refusal.reason] = done + 1 if count is None else count
            self._latest[refusal.reason] = refusal

    def snapshot(self) -> FeedHealth:
        """Return the counts so far."""
        with self._lock:
            rejections = tuple(
                Rejection(reason, self._counts[reason], self._latest[reason].detail,
                          self._latest[reason].fix)
                for reason in RejectReason if reason in self._counts)
            return FeedHealth(self.topic, self.noun, self._received, self._accepted, rejections,
                              self._last_ns)


def qos_refusal(policy: str, best_effort: bool) -> Refusal:
    """Return the refusal for a publisher whose QoS policy `policy` the subscription cannot match.

    Args:
        policy: The incompatible policy's name (rclpy's ``QoSPolicyKind``), e.g.
            ``"RELIABILITY"``.
        best_effort: Whether the subscription is already best effort.
    """
    if policy == "RELIABILITY" and not best_effort:
        return Refusal(RejectReason.QOS_INCOMPATIBLE,
                       "publisher(s) offering incompatible QoS (RELIABILITY: the publisher is "
                       "best effort, hil subscribes reliable)",
                       "set [ros] best_effort_sensors = true")
    return Refusal(RejectReason.QOS_INCOMPATIBLE,
                   f"publisher(s) offering incompatible QoS ({policy})",
                   f"match the publisher's {policy} policy (see ros2 topic info -v)")


def frame_refusal(frame_id: str, expected: str) -> Refusal | None:
    """Return the refusal of a pose in `frame_id` when `expected` is configured; "" passes."""
    if not frame_id or frame_id == expected:
        return None
    return Refusal(RejectReason.FRAME_ID, f"frame_id {frame_id!r} (expected {expected!r})",
                   f'set [ros] pose_frame_id = "{frame_id}" and check [ros.transform] '
                   "maps that frame to the arena")


def pose_value_refusal(msg: Any) -> Refusal | None:
    """Return the refusal of a PoseWithCovarianceStamped's values, None when usable."""
    pose = msg.pose.pose
    q = pose.orientation
    values = [float(v) for v in (pose.position.x, pose.position.y, q.x, q.y, q.z, q.w)]
    if not all(math.isfinite(v) for v in values):
        return Refusal(RejectReason.NOT_FINITE,
                       "NaN or infinite poses (the rigid body occluded or not tracked)",
                       "check the mocap sees and tracks the vessel's rigid body")
    norm = math.sqrt(sum(v * v for v in values[2:]))
    if abs(norm - 1.0) > _UNIT_TOLERANCE:
        return Refusal(RejectReason.BAD_QUATERNION,
                       f"orientations not a unit quaternion (norm {norm:.3g})",
                       "check the driver publishes a normalized quaternion in ROS order "
                       "(x, y, z, w)")
    return None


def imu_value_refusal(msg: Any) -> Refusal | None:
    """Return the refusal of a sensor_msgs/Imu's planar values, None when usable."""
    values = (msg.linear_acceleration.x, msg.linear_acceleration.y, msg.angular_velocity.z)
    if all(math.isfinite(float(v)) for v in values):
        return None
    return Refusal(RejectReason.NOT_FINITE, "NaN or infinite IMU samples",
                   "check the IMU driver (a NaN is a sensor fault)")


def time_refusal(stamp_ns: int, last_ns: int | None, now_ns: int, stale_after_ns: int,
                 sim_time: bool) -> Refusal | None:
    """Return the refusal of a sample stamped `stamp_ns`, None when in order and fresh.

    Args:
        stamp_ns: The sample's header stamp (ns).
        last_ns: The stamp of the last sample accepted on the topic (ns); None: none yet.
        now_ns: The node clock's time (ns); 0 (sim time before /clock) skips the age check.
        stale_after_ns: Age beyond which a sample is stale (ns).
        sim_time: Whether the node follows /clock (names the clock in the fix).
    """
    if last_ns is not None and stamp_ns <= last_ns:
        return Refusal(RejectReason.OUT_OF_ORDER,
                       f"stamped at or before the previous sample (by "
                       f"{(last_ns - stamp_ns) / 1e6:.1f} ms)",
                       "check one publisher per topic, stamping at capture on a clock "
                       "that only moves forward")
    age_ns = now_ns - stamp_ns
    if now_ns > 0 and age_ns > stale_after_ns:
        clock = "/clock (use_sim_time = true)" if sim_time else "wall time"
        return Refusal(RejectReason.STALE,
                       f"stale (stamped {age_ns / NS_PER_S:.3g} s before hil's {clock})",
                       "check the time source: set [ros] use_sim_time to match the "
                       "publisher's clock, or synchronize the clocks (chrony)")
    return None
