"""The live telemetry's messages: decisions as strict JSON, events as rcl_interfaces/Log."""

from __future__ import annotations

import json
import math

import pytest

from hil.adapters.ros_telemetry import (
    Diagnostic,
    DiagnosticLevel,
    decision_from_json,
    decision_json,
    fill_diagnostic_array,
    fill_log_msg,
)
from hil.core.records import Decision, Event, EventLevel

DECISIONS = [
    Decision.from_arrays(12_000_000_001, [1.5, -2.25, 0.1 + 0.2], 1234, 17.0, True,
                         [[0.1, 0.0, 0.0], [0.2, 0.05, -0.1]], [3, 7], 7, 2, "sha256:abc",
                         reference_index=3, first=True, report_age_s=1.25, report_t_ns=5),
    Decision.from_arrays(0, [0, 0, 0], -1, math.inf, False, [], [], -1, 0, ""),
]


@pytest.mark.parametrize("decision", DECISIONS, ids=["winning", "outside"])
def test_a_decision_goes_out_as_strict_json_and_comes_back_the_same(decision: Decision) -> None:
    text = decision_json(decision)
    # Strict JSON (jq, browsers): +inf is null, never the Infinity literal.
    fields = json.loads(text, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))
    assert fields["t_ns"] == decision.t_ns
    assert fields["value"] == (None if math.isinf(decision.value) else decision.value)
    assert fields["safe_inputs"] == [list(row) for row in decision.safe_inputs]
    assert set(fields) == set(Decision.__dataclass_fields__)
    assert decision_from_json(text) == decision  # floats bit for bit


def test_an_event_fills_a_log_message() -> None:
    log = pytest.importorskip("rcl_interfaces.msg")
    msg = log.Log()
    fill_log_msg(msg, Event(3_000_000_007, EventLevel.ERROR, "pose_lost", "no pose for 0.5 s"))
    assert (msg.stamp.sec, msg.stamp.nanosec) == (3, 7)
    assert msg.level == log.Log.ERROR
    assert (msg.name, msg.msg) == ("hil.pose_lost", "no pose for 0.5 s")


def test_statuses_fill_a_diagnostic_array() -> None:
    diag = pytest.importorskip("diagnostic_msgs.msg")
    msg = diag.DiagnosticArray()
    statuses = [Diagnostic("hil_stack: pose feed", DiagnosticLevel.ERROR, "no poses for 2.0 s",
                           "/voyager/measurement/pose", (("received", "12"),)),
                Diagnostic("hil_stack: loop", DiagnosticLevel.STALE, "not running yet", "loop")]
    fill_diagnostic_array(msg, 1_500_000_000, statuses, diag.DiagnosticStatus, diag.KeyValue)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1, 500_000_000)
    assert [s.level for s in msg.status] == [diag.DiagnosticStatus.ERROR,
                                             diag.DiagnosticStatus.STALE]
    assert msg.status[0].hardware_id == "/voyager/measurement/pose"
    assert [(kv.key, kv.value) for kv in msg.status[0].values] == [("received", "12")]
    assert list(msg.status[1].values) == []
