"""Live telemetry of a run over ROS 2: decisions, events and ``/diagnostics``.

While ``hil vessel`` runs, the crew watches it with ``ros2 topic echo`` or Foxglove:

- :data:`DECISIONS` (``/hil/live/decision``), ``std_msgs/String``: one JSON object per
  decision of the symbolic controller (:func:`decision_json`), the fields of the
  recorded ``hil_msgs/Decision`` by name. The record has variable-length tables (the
  safe inputs, k x 3) that no standard message holds; hil's own message types cannot
  be published with rclpy from PyPI wheels (no generated Python package), so a
  documented JSON text is what every tool shows and every script parses
  (``ros2 topic echo --field data /hil/live/decision | jq``).
- :data:`EVENTS` (``/hil/live/events``), ``rcl_interfaces/Log``: each runtime event,
  its level as in ``/rosout`` (10 DEBUG ... 50 FATAL), ``name`` ``hil.<code>`` (e.g.
  ``hil.pose_lost``), ``msg`` the text; Foxglove's Log panel shows and filters them.
- :data:`DIAGNOSTICS` (``/diagnostics``), ``diagnostic_msgs/DiagnosticArray`` about once
  a second: feed health, premises, controller, loop (:class:`Diagnostic`; the statuses
  themselves are built by :mod:`hil.runs.live_diagnostics`).

The live topics sit under ``/hil/live/`` so they never share a name with the recorded
``/hil/...`` topics, which carry hil's own message types. Decisions and events are
published TRANSIENT_LOCAL, so a viewer that joins late still gets the last
:data:`LATE_JOINER_DEPTH` of each.

Publishing never waits on the control loop's thread: :class:`RosTelemetry` queues
(a bounded deque; the oldest is dropped and counted when full) and publishes from a
thread of its own. A publish that fails is reported once per topic through
`on_failure` (the run's log records it as an event) and never raised.
"""

from __future__ import annotations

import enum
import json
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from hil.core.clock import fill_stamp
from hil.core.codec import to_jsonable
from hil.core.records import Decision, Event

__all__ = [
    "DECISIONS",
    "DIAGNOSTICS",
    "EVENTS",
    "Diagnostic",
    "DiagnosticLevel",
    "RosTelemetry",
    "decision_from_json",
    "decision_json",
]

DECISIONS = "/hil/live/decision"
"""std_msgs/String: one JSON object per decision (:func:`decision_json`)."""
EVENTS = "/hil/live/events"
"""rcl_interfaces/Log: one message per runtime event."""
DIAGNOSTICS = "/diagnostics"
"""diagnostic_msgs/DiagnosticArray, about once a second."""
LATE_JOINER_DEPTH = 100
"""Decisions and events kept for subscribers that join late (TRANSIENT_LOCAL)."""
_QUEUE_LENGTH = 1000


class DiagnosticLevel(enum.IntEnum):
    """The levels of diagnostic_msgs/DiagnosticStatus."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


@dataclass(frozen=True, slots=True)
class Diagnostic:
    """One diagnostic_msgs/DiagnosticStatus.

    Attributes:
        name: What it is about, e.g. ``hil_stack: pose feed``.
        level: OK, WARN, ERROR, or STALE (no data yet).
        message: One line on the state, the worst finding first.
        hardware_id: The device or topic it is about.
        values: (key, value) pairs, values as text with their units.
    """

    name: str
    level: DiagnosticLevel
    message: str
    hardware_id: str
    values: tuple[tuple[str, str], ...] = ()


def decision_json(decision: Decision) -> str:
    """Return `decision` as one JSON object, the fields of hil_msgs/Decision by name.

    ``t_ns`` (run clock, ns), ``state`` [x m, y m, psi rad], ``cell``, ``value`` (steps
    to the target; null where +inf: not winning), ``winning``, ``safe_inputs``
    [[u m/s, v m/s, r rad/s], ...], ``safe_input_indices``, ``chosen_index`` (-1: none),
    ``chosen_input`` [u, v, r], ``controller_version``, ``scenario_hash``,
    ``reference_index`` (the input in force when deciding, -1 unknown), ``first``,
    ``report_age_s`` (null: not recorded), ``report_t_ns``. Strict JSON: no NaN or
    Infinity literals.
    """
    fields = to_jsonable(decision)
    if not math.isfinite(decision.value):
        fields["value"] = None
    return json.dumps(fields, allow_nan=False, separators=(",", ":"))


def decision_from_json(text: str) -> Decision:
    """Return the decision :func:`decision_json` wrote (the same record, bit for bit)."""
    fields = json.loads(text)
    fields["value"] = math.inf if fields["value"] is None else fields["value"]
    tuples = ("state", "safe_input_indices", "chosen_input")
    for key in tuples:
        fields[key] = tuple(fields[key])
    fields["safe_inputs"] = tuple(tuple(row) for row in fields["safe_inputs"])
    return Decision(**fields)


def fill_log_msg(msg: Any, event: Event) -> None:
    """Fill an rcl_interfaces/Log with `event`: stamp, level, ``hil.<code>``, text."""
    fill_stamp(msg.stamp, event.t_ns)
    msg.level = int(event.level)
    msg.name = f"hil.{event.code}"
    msg.msg = event.text


def fill_diagnostic_array(msg: Any, t_ns: int, diagnostics: Sequence[Diagnostic],
                          status_type: Any, key_value_type: Any) -> None:
    """Fill a diagnostic_msgs/DiagnosticArray stamped `t_ns` (ns) with `diagnostics`."""
    fill_stamp(msg.header.stamp, t_ns)
    statuses = []
    for d in diagnostics:
        status = status_type()
        status.level = bytes([int(d.level)])
        status.name, status.message, status.hardware_id = d.name, d.message, d.hardware_id
        status.values = [key_value_type(key=k, value=v) for k, v in d.values]
        statuses.append(status)
    msg.status = statuses


Diagnose = Callable[[], Sequence[Diagnostic]]
"""Returns the statuses of the moment (called on the telemetry thread)."""


class RosTelemetry:
    """Publishes decisions, events and diagnostics on a node, from a thread of its own.

    :meth:`decision` and :meth:`event` only queue (constant time, never blocking);
    :meth:`start` starts the thread, which publishes what is queued as it comes and the
    statuses of `diagnose` every `period_s`; :meth:`close` publishes what is left and
    stops it. Create it before the node spins far: the publishers are made here.

    Args:
        node: An open rclpy node (the stack's world's).
        now_ns: The node clock (ns), for the diagnostics' stamp.
        on_failure: Told once per topic that a publish failed (why, in words).
        period_s: Seconds between two diagnostic arrays.

    Raises:
        ImportError: The message packages are missing (std_msgs, rcl_interfaces,
            diagnostic_msgs).
    """

    def __init__(self, node: Any, now_ns: Callable[[], int],
                 on_failure: Callable[[str], None], period_s: float = 1.0) -> None:
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
        from rcl_interfaces.msg import Log
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import String

        kept = QoSProfile(depth=LATE_JOINER_DEPTH, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._publishers = {
            DECISIONS: node.create_publisher(String, DECISIONS, kept),
            EVENTS: node.create_publisher(Log, EVENTS, kept),
            DIAGNOSTICS: node.create_publisher(DiagnosticArray, DIAGNOSTICS, 10),
        }
        self._types = (String, Log, DiagnosticArray, DiagnosticStatus, KeyValue)
        self._now_ns = now_ns
        self._on_failure = on_failure
        self._period_s = period_s
        self._queue: deque[Decision | Event] = deque(maxlen=_QUEUE_LENGTH)
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._diagnose: Diagnose | None = None
        self._failed: set[str] = set()
        self.dropped = 0
        """Decisions and events dropped because the queue was full (never published)."""
        self.published = dict.fromkeys(self._publishers, 0)
        """Messages published per topic."""

    def decision(self, decision: Decision) -> None:
        """Queue a decision for :data:`DECISIONS`."""
        self._put(decision)

    def event(self, event: Event) -> None:
        """Queue an event for :data:`EVENTS`."""
        self._put(event)

    def _put(self, item: Decision | Event) -> None:
        if len(self._queue) == self._queue.maxlen:
            self.dropped += 1
        self._queue.append(item)
        self._wake.set()

    def start(self, diagnose: Diagnose) -> None:
        """Start publishing: the queue as it fills, `diagnose`'s statuses every period."""
        self._diagnose = diagnose
        self._thread = threading.Thread(target=self._run, name="hil-telemetry", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        next_s = time.monotonic()
        while not self._stop.is_set():
            self._drain()
            if time.monotonic() >= next_s:
                next_s = max(next_s + self._period_s, time.monotonic())
                self.publish_diagnostics()
            self._wake.wait(max(0.0, next_s - time.monotonic()))
            self._wake.clear()

    def _drain(self) -> None:
        string_type, log_type = self._types[0], self._types[1]
        while self._queue:
            item = self._queue.popleft()
            if isinstance(item, Decision):
                msg = string_type()
                msg.data = decision_json(item)
                self._publish(DECISIONS, msg)
            else:
                msg = log_type()
                fill_log_msg(msg, item)
                self._publish(EVENTS, msg)

    def publish_diagnostics(self) -> None:
        """Publish the statuses `diagnose` returns now (a failure is reported, not raised)."""
        if self._diagnose is None:
            return
        _, _, array_type, status_type, key_value_type = self._types
        try:
            msg = array_type()
            fill_diagnostic_array(msg, max(0, self._now_ns()), self._diagnose(), status_type,
                                  key_value_type)
        except Exception as err:  # a status that cannot be built must not end the run
            self._failed_once(DIAGNOSTICS, f"cannot build the diagnostics: {err!r}")
            return
        self._publish(DIAGNOSTICS, msg)

    def _publish(self, topic: str, msg: Any) -> None:
        try:
            self._publishers[topic].publish(msg)
        except Exception as err:  # rclpy raises its own types (context shut down, ...)
            self._failed_once(topic, f"cannot publish on {topic}: {err!r}")
            return
        self.published[topic] += 1

    def _failed_once(self, topic: str, text: str) -> None:
        if topic not in self._failed:
            self._failed.add(topic)
            self._on_failure(f"{text}; the run goes on, its log keeps everything")

    def close(self) -> None:
        """Publish what is queued and stop the thread (closing twice does nothing)."""
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        self._drain()
