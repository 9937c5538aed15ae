"""Replay results: statuses, readable report, JSON summary and JUnit XML."""

from __future__ import annotations

import dataclasses
import json
import math
from xml.etree import ElementTree as ET

import pytest

from hil.replay.regression import (
    Check,
    Finding,
    Interval,
    LogReport,
    Status,
    exit_code,
    jsonl_lines,
    junit_xml,
    render,
    summary_json,
    verdict_jsonl,
    verdict_line,
)

DECISION_DIFF = Finding(
    "chosen input differ at state [1.0, 2.0, 0.5]",
    12_050_000_000,
    {"recorded": {"chosen": 3}, "replayed": {"chosen": 7}, "value": math.inf},
)


def _good() -> LogReport:
    return LogReport(
        "logs/a",
        (
            Check("decisions", Status.PASS, "37 decisions reproduced"),
            Check("margin", Status.WARN, "outside the margin", (Finding("surge", 50_000_000),)),
        ),
        ("bag: a warning",),
        wall_s=1.5,
    )


def _bad() -> LogReport:
    return LogReport(
        "logs/b",
        (Check("decisions", Status.FAIL, "1 of 37 decisions differ", (DECISION_DIFF,)),),
        wall_s=2.0,
    )


def _broken() -> LogReport:
    return LogReport("logs/c", error="'logs/c' does not exist")


def test_status_is_the_worst_check_and_error_wins() -> None:
    assert _good().status is Status.WARN
    assert _bad().status is Status.FAIL
    assert _broken().status is Status.ERROR
    assert LogReport("x").status is Status.PASS
    assert Status.worst([Status.SKIP, Status.PASS]) is Status.SKIP
    # A check not judged does not make a judged log SKIP; only a log with none judged is.
    skipped = Check("stack", Status.SKIP, "not judged")
    passed = Check("decisions", Status.PASS, "ok")
    assert LogReport("x", (passed, skipped)).status is Status.PASS
    assert LogReport("x", (skipped,)).status is Status.SKIP


def test_exit_code() -> None:
    assert exit_code([_good()]) == 0
    assert exit_code([_good(), _bad()]) == 1
    assert exit_code([_bad(), _broken()]) == 2
    assert exit_code([]) == 2  # nothing replayed is no verdict


def test_regressions_are_the_findings_of_failed_checks() -> None:
    assert _good().regressions == ()
    assert _bad().regressions == (DECISION_DIFF,)
    assert _bad().check("decisions").status is Status.FAIL
    with pytest.raises(KeyError, match="no check 'stack'"):
        _bad().check("stack")


def test_render_names_time_and_both_sides() -> None:
    text = render(_bad())
    assert text.splitlines()[0] == "logs/b: FAIL (2.00 s)"
    assert "[ FAIL] decisions: 1 of 37 decisions differ" in text
    assert "t=12.050 s: chosen input differ at state [1.0, 2.0, 0.5]" in text
    assert "warning: bag: a warning" in render(_good())
    assert "error: 'logs/c' does not exist" in render(_broken())


def test_render_caps_findings() -> None:
    many = tuple(Finding(f"f{i}", i) for i in range(9))
    report = LogReport("x", (Check("stack", Status.FAIL, "s", many),))
    assert "... and 6 more" in render(report, max_findings=3)


def test_summary_json_is_one_line_with_totals_and_no_nan() -> None:
    line = summary_json([_good(), _bad(), _broken()])
    assert "\n" not in line
    data = json.loads(line)
    assert (data["logs"], data["passed"], data["failed"], data["errors"]) == (3, 1, 1, 1)
    assert data["exit_code"] == 2
    finding = data["reports"][1]["checks"][0]["findings"][0]
    assert finding["t_ns"] == 12_050_000_000
    assert finding["value"] is None  # inf is not JSON
    assert finding["replayed"] == {"chosen": 7}


def test_junit_xml_has_a_case_per_check_and_marks_failures() -> None:
    root = ET.fromstring(junit_xml([_good(), _bad(), _broken()]))
    suite = root.find("testsuite")
    assert suite is not None
    assert (suite.get("tests"), suite.get("failures"), suite.get("errors")) == ("4", "1", "1")
    cases = {(c.get("classname"), c.get("name")): c for c in suite.iter("testcase")}
    failure = cases[("logs/b", "decisions")].find("failure")
    assert failure is not None
    assert "t=12.050 s" in (failure.text or "")
    error = cases[("logs/c", "replay")].find("error")
    assert error is not None
    assert "does not exist" in (error.get("message") or "")
    assert cases[("logs/a", "decisions")].find("failure") is None


def test_verdict_line_counts_the_logs_with_warnings() -> None:
    assert verdict_line([_good()]) == "1 log(s): no regression (1 with warnings to look at)"
    clean = LogReport("logs/d", (Check("decisions", Status.PASS, "ok"),))
    assert verdict_line([clean]) == "1 log(s): no regression"
    assert verdict_line([clean, _bad()]) == "2 log(s): REGRESSION"
    assert verdict_line([_bad(), _broken()]).endswith("ERROR: some logs could not be replayed")
    assert verdict_line([]) == "0 log(s): ERROR: no log to replay"


def test_jsonl_lines_are_the_intervals_then_the_log() -> None:
    interval = Interval(
        50_000_000,
        2_050_000_000,
        (1.0, 2.0, 0.5),
        3,
        (0.1, 0.0, 0.0),
        successor_contained=True,
        tube_contained=False,
        value_decreased=True,
        tube_distance_m=0.031,
        successor_distance_m=0.0,
        heading_distance_rad=0.0,
        tracking_rms=(0.01, 0.02, 1.5),
        tracking_max=(0.05, 0.06, 4.0),
        envelope_exceeded=("sway",),
        envelope_excess=(0.0, 0.004, 0.0),
        status=Status.WARN,
        notes=("left the tube",),
    )
    report = dataclasses.replace(_good(), intervals=(interval,))
    first, log = (json.loads(line) for line in jsonl_lines(report))
    assert first["type"] == "interval"
    assert first["log"] == "logs/a"
    assert first["t_s"] == 0.05
    assert first["successor_contained"] is True
    assert first["tube_contained"] is False
    assert first["envelope_exceeded"] == ["sway"]
    assert first["envelope_excess"] == [0.0, 0.004, 0.0]
    assert first["tube_distance_m"] == 0.031
    assert first["value_decreased"] is True
    assert first["verdict"] == "warn"
    assert log == {
        "type": "log",
        "log": "logs/a",
        "verdict": "warn",
        "error": "",
        "intervals": 1,
        "checks": {"decisions": "pass", "margin": "warn"},
        "wall_s": 1.5,
    }
    last = json.loads(verdict_jsonl([_good(), _broken()]))
    assert (last["type"], last["verdict"], last["exit_code"], last["errors"]) == (
        "verdict",
        "error",
        2,
        1,
    )
