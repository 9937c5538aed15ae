"""Results of a replay: checks and findings as frozen data, rendered as text, JSON and JUnit.

A replay of one log produces a :class:`LogReport`: a list of :class:`Check` s
(decisions, tracking, contract, stack, resim), each with a :class:`Status` and
the :class:`Finding` s behind it (time, what differs, both sides), and the
:class:`Interval` s between its decisions, judged one by one. A FAIL in any check
is a regression; WARN is something to act on that does not fail (the guarantee's
assumption broken); figures kept for comparison (the paper's tank tracking
error) are no warning. ERROR means the log could not be replayed at all (missing,
foreign, another scenario).
"""

from __future__ import annotations

import enum
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any
from xml.etree import ElementTree as ET

from hil.core.clock import NS_PER_S
from hil.core.records import Decision


class Status(enum.Enum):
    """Outcome of a check or of a whole log, worst last."""

    PASS = "pass"
    SKIP = "skip"
    WARN = "warn"
    FAIL = "fail"
    ERROR = "error"

    @property
    def rank(self) -> int:
        """Severity order: pass < skip < warn < fail < error."""
        return list(Status).index(self)

    @staticmethod
    def worst(statuses: Sequence[Status]) -> Status:
        """Return the most severe of `statuses` (PASS when empty)."""
        return max(statuses, key=lambda s: s.rank, default=Status.PASS)


def _clean(value: Any) -> Any:
    """Make a value JSON-safe: tuples to lists, NaN and inf to None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    return value


@dataclass(frozen=True)
class Finding:
    """One difference or observation.

    Attributes:
        message: One readable line.
        t_ns: Time in the run it refers to (ns); None for the whole run.
        data: Both sides in machine-readable form (recorded, replayed, state, ...).
    """

    message: str
    t_ns: int | None = None
    data: dict[str, Any] = field(default_factory=dict, hash=False)

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary."""
        return _clean({"t_ns": self.t_ns, "message": self.message, **self.data})  # type: ignore[no-any-return]


@dataclass(frozen=True)
class Check:
    """One comparison of the replay with the recording or with a threshold.

    Attributes:
        name: Short name ("decisions", "tracking", "contract", "stack", "resim").
        status: Outcome.
        summary: One line.
        findings: The differences behind the outcome, in time order.
        metrics: Numbers worth keeping (tracking RMS, counts), JSON-ready.
        intervals: The intervals judged one by one, for the check that judges them
            (``contract``); kept in the report with ``ReplayOptions.intervals``.
    """

    name: str
    status: Status
    summary: str
    findings: tuple[Finding, ...] = ()
    metrics: dict[str, Any] = field(default_factory=dict, hash=False)
    intervals: tuple[Interval, ...] = field(default=(), compare=False, hash=False)

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary."""
        return {
            "name": self.name,
            "status": self.status.value,
            "summary": self.summary,
            "metrics": _clean(self.metrics),
            "findings": [f.to_dict() for f in self.findings],
        }


@dataclass(frozen=True)
class Interval:
    """One judged interval: from a recorded decision to the next (or the end of the run).

    Attributes:
        t_ns: Decision time, the interval's start (ns).
        end_ns: The next decision's time or the run's last stamp (ns).
        state: Estimated state (x m, y m, psi rad) the decision was taken at.
        chosen_index: Input-grid index of the chosen input, -1 for none.
        chosen_input: The chosen (u m/s, v m/s, r rad/s).
        successor_contained: Whether the estimate at the next decision (or at tau +
            late when none) lies in the decision contract's successor cells, position
            and heading; None when not judged (no input chosen, no controller, the
            interval cut short before tau, the run ended first).
        tube_contained: Whether every estimate sample of the interval (up to tau +
            late) lies within the estimation bound of the tube cells; None when not judged.
        value_decreased: Whether the value at the successor estimate, chosen input in
            force, is below the decision's; None when not judged.
        tube_distance_m: Farthest estimate sample from the tube cells (m).
        successor_distance_m: Distance of the successor estimate to the successor
            cells (m).
        heading_distance_rad: Angle of the successor estimate to the successor
            headings (rad).
        tracking_rms: Tracking-error RMS over the interval (surge m/s, sway m/s,
            yaw deg/s); None without samples.
        tracking_max: Largest |tracking error| over the interval (same units).
        envelope_exceeded: Axes on which |nu_hat - nu_ref| left the budget's envelope
            of the decision's class plus the velocity estimate's tolerance.
        envelope_excess: Largest excess over that bound per axis (surge m/s, sway m/s,
            yaw deg/s; 0 within it); None when not judged.
        status: PASS, or FAIL (the contract broken, or a check failed at a time in the
            interval).
        notes: Why the interval is not PASS, one short line each.
        late_s: How much longer than tau + late its input was held before the next
            decision (s): a broken premise (a stalled loop); None when in time.
    """

    t_ns: int
    end_ns: int
    state: tuple[float, float, float]
    chosen_index: int
    chosen_input: tuple[float, float, float]
    successor_contained: bool | None = None
    tube_contained: bool | None = None
    value_decreased: bool | None = None
    tube_distance_m: float | None = None
    successor_distance_m: float | None = None
    heading_distance_rad: float | None = None
    tracking_rms: tuple[float, float, float] | None = None
    tracking_max: tuple[float, float, float] | None = None
    envelope_exceeded: tuple[str, ...] = ()
    envelope_excess: tuple[float, float, float] | None = None
    status: Status = Status.PASS
    notes: tuple[str, ...] = ()
    late_s: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary (times in ns and s)."""
        return _clean(  # type: ignore[no-any-return]
            {
                "t_ns": self.t_ns,
                "late_s": self.late_s,
                "t_s": self.t_ns / NS_PER_S,
                "end_ns": self.end_ns,
                "state": self.state,
                "chosen_index": self.chosen_index,
                "chosen_input": self.chosen_input,
                "successor_contained": self.successor_contained,
                "tube_contained": self.tube_contained,
                "value_decreased": self.value_decreased,
                "tube_distance_m": self.tube_distance_m,
                "successor_distance_m": self.successor_distance_m,
                "heading_distance_rad": self.heading_distance_rad,
                "tracking_rms": self.tracking_rms,
                "tracking_max": self.tracking_max,
                "envelope_exceeded": list(self.envelope_exceeded),
                "envelope_excess": self.envelope_excess,
                "verdict": self.status.value,
                "notes": list(self.notes),
            }
        )


@dataclass(frozen=True)
class LogReport:
    """The replay of one log.

    Attributes:
        path: The log as given.
        checks: The checks run, in order.
        warnings: What was skipped or odd while reading the log.
        error: Why the log could not be replayed ("" when it could).
        wall_s: Wall time of the replay (s).
        intervals: The intervals between decisions, judged one by one (empty when
            not asked for or when the log holds no decisions).
        notes: What the reader should know to read the report (for a lab bag: the
            transform used, what cannot be judged without hil's topics), one line each.
        replayed: Decisions the replay took where the log holds none to compare
            with (a lab bag's stack re-run), for the ``.rrd``.
    """

    path: str
    checks: tuple[Check, ...] = ()
    warnings: tuple[str, ...] = ()
    error: str = ""
    wall_s: float = 0.0
    intervals: tuple[Interval, ...] = ()
    notes: tuple[str, ...] = ()
    replayed: tuple[Decision, ...] = ()

    @property
    def status(self) -> Status:
        """ERROR when it could not be replayed, else the worst judged check.

        A check not judged (SKIP) does not make the log SKIP unless none was judged.
        """
        if self.error:
            return Status.ERROR
        judged = [c.status for c in self.checks if c.status is not Status.SKIP]
        if not judged and self.checks:
            return Status.SKIP
        return Status.worst(judged)

    @property
    def regressions(self) -> tuple[Finding, ...]:
        """Every finding of a failed check."""
        return tuple(f for c in self.checks if c.status is Status.FAIL for f in c.findings)

    def check(self, name: str) -> Check:
        """Return the check called `name`.

        Raises:
            KeyError: No such check was run.
        """
        for c in self.checks:
            if c.name == name:
                return c
        raise KeyError(f"no check {name!r} in the report of {self.path!r}")

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary."""
        return {
            "path": self.path,
            "status": self.status.value,
            "error": self.error,
            "wall_s": round(self.wall_s, 3),
            "warnings": list(self.warnings),
            "notes": list(self.notes),
            "checks": [c.to_dict() for c in self.checks],
        }


def exit_code(reports: Sequence[LogReport]) -> int:
    """Return the exit status of a replay.

    0: every log replayed and none regressed (warnings do not count); 1: a log
    regressed; 2: a log could not be read or replayed, whatever the others did
    (their regressions are still in the reports), or there was no log at all.
    """
    if not reports:
        return 2
    statuses = [r.status for r in reports]
    if Status.ERROR in statuses:
        return 2
    return 1 if Status.FAIL in statuses else 0


def time_s(t_ns: int | None) -> str:
    """Format a run time for people: seconds with ms."""
    return "-" if t_ns is None else f"t={t_ns / NS_PER_S:.3f} s"


_MARK = {
    Status.PASS: "ok",
    Status.SKIP: "skip",
    Status.WARN: "WARN",
    Status.FAIL: "FAIL",
    Status.ERROR: "ERROR",
}


def render(report: LogReport, max_findings: int = 5) -> str:
    """Return the readable report of one log.

    Args:
        report: The report.
        max_findings: Findings shown per check; the rest are counted.
    """
    lines = [f"{report.path}: {report.status.value.upper()} ({report.wall_s:.2f} s)"]
    if report.error:
        lines.append(f"  error: {report.error}")
    for check in report.checks:
        lines.append(f"  [{_MARK[check.status]:>5}] {check.name}: {check.summary}")
        shown = check.findings  # a passing check's are figures (a lab bag's decisions)
        for finding in shown[:max_findings]:
            where = f"{time_s(finding.t_ns)}: " if finding.t_ns is not None else ""
            lines.append(f"          {where}{finding.message}")
        if len(shown) > max_findings:
            lines.append(f"          ... and {len(shown) - max_findings} more")
    lines.extend(f"  warning: {warning}" for warning in report.warnings)
    lines.extend(f"  note: {note}" for note in report.notes)
    return "\n".join(lines)


def verdict_line(reports: Sequence[LogReport]) -> str:
    """Return the last line of a replay: how many logs, the verdict, the warnings."""
    code = exit_code(reports)
    warned = sum(r.status is Status.WARN for r in reports)
    verdict = {
        0: "no regression",
        1: "REGRESSION",
        2: "ERROR: some logs could not be replayed" if reports else "ERROR: no log to replay",
    }[code]
    note = f" ({warned} with warnings to look at)" if warned else ""
    return f"{len(reports)} log(s): {verdict}{note}"


def summary_json(reports: Sequence[LogReport]) -> str:
    """Return every report and the totals as one line of JSON."""
    statuses = [r.status for r in reports]
    data = {
        "status": Status.worst(statuses).value,
        "exit_code": exit_code(reports),
        "logs": len(reports),
        "passed": sum(s in (Status.PASS, Status.WARN, Status.SKIP) for s in statuses),
        "failed": statuses.count(Status.FAIL),
        "errors": statuses.count(Status.ERROR),
        "warned": statuses.count(Status.WARN),
        "reports": [r.to_dict() for r in reports],
    }
    return json.dumps(data, sort_keys=True)


def jsonl_lines(report: LogReport) -> list[str]:
    """Return the JSON lines of one log: one per judged interval, then the log's own line.

    Each interval line has ``"type": "interval"`` and the fields of
    :meth:`Interval.to_dict`; the log line (``"type": "log"``) the log's verdict,
    error and the status of every check.
    """
    lines = [
        json.dumps({"type": "interval", "log": report.path, **i.to_dict()}, sort_keys=True)
        for i in report.intervals
    ]
    log = {
        "type": "log",
        "log": report.path,
        "verdict": report.status.value,
        "error": report.error,
        "intervals": len(report.intervals),
        "checks": {c.name: c.status.value for c in report.checks},
        "wall_s": round(report.wall_s, 3),
    }
    lines.append(json.dumps(log, sort_keys=True))
    return lines


def verdict_jsonl(reports: Sequence[LogReport]) -> str:
    """Return the last JSON line of a replay: the overall verdict and its exit status."""
    statuses = [r.status for r in reports]
    data = {
        "type": "verdict",
        "verdict": Status.worst(statuses).value if reports else Status.ERROR.value,
        "exit_code": exit_code(reports),
        "logs": len(reports),
        "failed": statuses.count(Status.FAIL),
        "errors": statuses.count(Status.ERROR),
        "warned": statuses.count(Status.WARN),
    }
    return json.dumps(data, sort_keys=True)


def junit_xml(reports: Sequence[LogReport], suite: str = "hil replay") -> str:
    """Return JUnit XML: one test suite, one test case per (log, check).

    A log that could not be replayed is one test case with an error.
    """
    root = ET.Element("testsuites")
    cases = sum(max(1, len(r.checks)) if not r.error else 1 for r in reports)
    failures = sum(c.status is Status.FAIL for r in reports for c in r.checks)
    errors = sum(bool(r.error) for r in reports)
    skipped = sum(c.status is Status.SKIP for r in reports for c in r.checks)
    wall = sum(r.wall_s for r in reports)
    ts = ET.SubElement(
        root,
        "testsuite",
        name=suite,
        tests=str(cases),
        failures=str(failures),
        errors=str(errors),
        skipped=str(skipped),
        time=f"{wall:.3f}",
    )
    for report in reports:
        if report.error:
            case = ET.SubElement(ts, "testcase", classname=report.path, name="replay", time="0")
            ET.SubElement(case, "error", message=report.error).text = report.error
            continue
        share = report.wall_s / max(1, len(report.checks))
        for check in report.checks:
            case = ET.SubElement(
                ts, "testcase", classname=report.path, name=check.name, time=f"{share:.3f}"
            )
            text = "\n".join(
                f"{time_s(f.t_ns)}: {f.message}" if f.t_ns is not None else f.message
                for f in check.findings
            )
            if check.status is Status.FAIL:
                ET.SubElement(case, "failure", message=check.summary).text = text
            elif check.status is Status.SKIP:
                ET.SubElement(case, "skipped", message=check.summary)
            elif check.status is Status.WARN:
                ET.SubElement(case, "system-out").text = f"WARN: {check.summary}\n{text}"
        if report.warnings and len(ts):
            ET.SubElement(ts[-1], "system-err").text = "\n".join(report.warnings)
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True)
