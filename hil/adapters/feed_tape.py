"""What a sensor subscription delivered, message by message: arrival, stamp, values, frame.

The preflight (:mod:`hil.adapters.ros_listen`) keeps every message it hears; the stack's
ROS world (:mod:`hil.adapters.ros`) keeps the newest few seconds, so that the live
diagnostics judge the feed against the guarantee's premises as the preflight does
(:mod:`hil.runs.feed_check`).
"""

from __future__ import annotations

import threading
from collections import deque
from dataclasses import dataclass

__all__ = ["FeedTape", "Heard"]


@dataclass(frozen=True, slots=True)
class Heard:
    """What one topic delivered.

    Attributes:
        topic: The ROS topic.
        arrival_ns: Node-clock arrival time of each message (ns), in order of arrival.
        stamp_ns: Each message's header stamp (ns).
        finite: Whether each message's values were all finite.
        frame_ids: Each message's header.frame_id.
        qos_refusals: Incompatible-QoS events (publishers the subscription cannot match).
    """

    topic: str
    arrival_ns: tuple[int, ...]
    stamp_ns: tuple[int, ...]
    finite: tuple[bool, ...]
    frame_ids: tuple[str, ...]
    qos_refusals: int


class FeedTape:
    """Per-message records of one subscription, appended from the executor thread.

    Args:
        topic: The ROS topic.
        maxlen: Messages kept, the newest (None: all).
    """

    def __init__(self, topic: str, maxlen: int | None = None) -> None:
        self.topic = topic
        self._rows: deque[tuple[int, int, bool, str]] = deque(maxlen=maxlen)
        self.qos_refusals = 0
        self._lock = threading.Lock()

    def append(self, arrival_ns: int, stamp_ns: int, finite: bool, frame_id: str) -> None:
        """Record one message: arrival on the node clock and header stamp (ns)."""
        with self._lock:
            self._rows.append((arrival_ns, stamp_ns, finite, frame_id))

    def __len__(self) -> int:
        with self._lock:
            return len(self._rows)

    def clear(self) -> None:
        """Forget the messages recorded so far (the QoS refusals are kept)."""
        with self._lock:
            self._rows.clear()

    def heard(self, since_ns: int | None = None) -> Heard:
        """Return the messages recorded, those that arrived at or after `since_ns` if given."""
        with self._lock:
            rows = [r for r in self._rows if since_ns is None or r[0] >= since_ns]
        arrival, stamp, finite, frames = zip(*rows, strict=True) if rows else ((), (), (), ())
        return Heard(self.topic, tuple(arrival), tuple(stamp), tuple(finite), tuple(frames),
                     self.qos_refusals)
