"""End to end over real DDS: `hil vessel` publishes its decisions, events and diagnostics.

`hil sim-vessel` (wall time) feeds `hil vessel`; a listener in this process subscribes to
``/hil/live/decision``, ``/hil/live/events`` and ``/diagnostics`` the way `ros2 topic
echo` does. Once two decisions came, the simulated vessel is stopped (the pose feed
cut): the pose feed's status must turn ERROR. After the stack is stopped, the live
decisions must be the recorded ones, field for field, and the live events the recorded
events.
"""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from hil.bag.reader import BagReader
from hil.core.records import Decision, Event, EventLevel

pytest.importorskip("rclpy")
pytest.importorskip("diagnostic_msgs")
pytestmark = pytest.mark.ros

from hil.adapters.ros import spin_in_thread, stop_spinning  # noqa: E402
from hil.adapters.ros_telemetry import (  # noqa: E402
    DECISIONS,
    DIAGNOSTICS,
    EVENTS,
    DiagnosticLevel,
    decision_from_json,
)
from tests.runs.dds_processes import dds_env, own_domain, stop  # noqa: E402

HIL = [sys.executable, "-m", "hil"]
STATUSES = ("pose feed", "IMU feed", "premises", "controller", "loop")

Status = tuple[DiagnosticLevel, str, str, dict[str, str]]
"""A received status: level, message, hardware id, values."""


class Heard:
    """What the listener received, appended from its executor thread."""

    def __init__(self) -> None:
        self.decisions: list[Decision] = []
        self.events: list[Event] = []
        self.arrays: list[dict[str, Status]] = []
        self.lock = threading.Lock()

    def on_decision(self, msg: Any) -> None:
        with self.lock:
            self.decisions.append(decision_from_json(msg.data))

    def on_event(self, msg: Any) -> None:
        assert msg.name.startswith("hil.")
        t_ns = msg.stamp.sec * 1_000_000_000 + msg.stamp.nanosec
        with self.lock:
            self.events.append(Event(t_ns, EventLevel(msg.level), msg.name[4:], msg.msg))

    def on_diagnostics(self, msg: Any) -> None:
        array = {s.name: (DiagnosticLevel(s.level[0]), s.message, s.hardware_id,
                          {kv.key: kv.value for kv in s.values}) for s in msg.status}
        with self.lock:
            self.arrays.append(array)

    def wait(self, what: Callable[[Heard], bool], timeout_s: float) -> bool:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            with self.lock:
                if what(self):
                    return True
            time.sleep(0.1)
        return False


@contextmanager
def listening(domain: int) -> Iterator[Heard]:
    """Subscribe to the live topics on `domain` as a viewer would, for the block."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rcl_interfaces.msg import Log
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    heard = Heard()
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain)
    node = rclpy.create_node("telemetry_listener", context=context)
    kept = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)
    node.create_subscription(String, DECISIONS, heard.on_decision, kept)
    node.create_subscription(Log, EVENTS, heard.on_event, kept)
    node.create_subscription(DiagnosticArray, DIAGNOSTICS, heard.on_diagnostics, 50)
    executor, thread = spin_in_thread(context, node, "telemetry-listener")
    try:
        yield heard
    finally:
        stop_spinning(context, node, executor, thread)


SILENT = "/voyager/measurement/pose messages"  # the premise line of a period without a pose


def _pose_level(level: DiagnosticLevel, after: int = 0,
                silent: bool = False) -> Callable[[Heard], bool]:
    """Whether an array from the `after`-th on had the pose feed at `level` (and no pose).

    `silent`: its premises judged a whole period without a pose ("0 received"; the period in
    which the feed was cut may have heard one, and the stack may be stopped before the next).
    """
    return lambda h: any(a["hil_stack: pose feed"][0] is level
                         and (not silent or a["hil_stack: premises"][3].get(SILENT, "")
                              .startswith("FAILED: 0 received"))
                         for a in h.arrays[after:])


def _order(event: Event) -> tuple[int, str, str]:
    return event.t_ns, event.code, event.text


def test_vessel_publishes_decisions_events_and_diagnostics(tmp_path: Path) -> None:
    domain = own_domain(140, 10)
    config = tmp_path / "vessel.toml"
    config.write_text(f'scenario = "coarse"\n[ros]\ndomain_id = {domain}\n'
                      "[loop]\nmax_duration_s = 300.0\n")
    out = tmp_path / "run"
    env = dds_env(domain)
    with listening(domain) as heard:
        vessel = subprocess.Popen([*HIL, "sim-vessel", "coarse", "--domain-id", str(domain)],
                                  env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        stack = subprocess.Popen([*HIL, "vessel", "--config", str(config), "--out", str(out)],
                                 env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                 text=True)
        try:
            assert heard.wait(lambda h: len(h.decisions) >= 2, 240.0), heard.arrays[-1:]
            assert heard.wait(_pose_level(DiagnosticLevel.OK), 5.0), heard.arrays[-1:]
            stop(vessel)  # the pose feed is cut
            with heard.lock:
                cut_at = len(heard.arrays)
            assert heard.wait(_pose_level(DiagnosticLevel.ERROR, cut_at, silent=True), 30.0), \
                heard.arrays[-3:]
        finally:
            stop(vessel)
            status = stop(stack)
        _, stderr = stack.communicate()
        assert status == 1, stderr[-3000:]
        # The last events (stopped) are published before the stack's node goes.
        assert heard.wait(lambda h: any(e.code == "stopped" for e in h.events), 10.0), \
            [e.code for e in heard.events]
    with BagReader(out) as reader:
        recorded = [r for _, _, r in reader.records(["/hil/decision", "/hil/events"])]
    decisions = [r for r in recorded if isinstance(r, Decision)]
    events = [r for r in recorded if isinstance(r, Event)]
    assert len(decisions) >= 2
    assert heard.decisions == decisions
    assert sorted(heard.events, key=_order) == sorted(events, key=_order)
    assert {"controller_ready", "pose_lost", "stopped"} <= {e.code for e in events}
    assert "telemetry_failed" not in {e.code for e in events}
    for array in heard.arrays:
        assert sorted(array) == sorted(f"hil_stack: {s}" for s in STATUSES)
    ok = next(a for a in heard.arrays if a["hil_stack: pose feed"][0] is DiagnosticLevel.OK)
    _, _, hardware_id, values = ok["hil_stack: pose feed"]
    assert hardware_id == "/voyager/measurement/pose"
    assert int(values["accepted"]) > 0
    assert values["rejected"] == "0"
    cut = next(a for a in heard.arrays[cut_at:]
               if a["hil_stack: pose feed"][0] is DiagnosticLevel.ERROR)
    assert "no poses for" in cut["hil_stack: pose feed"][1]
    # The premises are judged on each period: a later one heard no pose at all.
    silent = [a["hil_stack: premises"] for a in heard.arrays[cut_at:]
              if SILENT in a["hil_stack: premises"][3]]
    assert all(p[0] is DiagnosticLevel.WARN for p in silent)
    assert silent[-1][3][SILENT].startswith("FAILED: 0 received")
    versions = {a["hil_stack: controller"][3]["controller version"] for a in heard.arrays}
    assert str(decisions[-1].controller_version) in versions
