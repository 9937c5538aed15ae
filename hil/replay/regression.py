"""Results of a replay: checks and findings as frozen data, rendered as text, JSON and JUnit.

A replay of one log produces a :class:`LogReport`: a list of :class:`Check` s
(decisions, tracking, margin, stack, resim), each with a :class:`Status` and
the :class:`Finding` s behind it (time, what differs, both sides). A FAIL in any
check is a regression; WARN is reported but does not fail; ERROR means the log
could not be replayed at all (missing, foreign, another scenario).
"""

from __future__ import annotations

import enum
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any
from xml.etree import ElementTree as ET

NS_PER_S = 1_000_000_000


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
        name: Short name ("decisions", "tracking", "margin", "stack", "resim").
        status: Outcome.
        summary: One line.
        findings: The differences behind the outcome, in time order.
        metrics: Numbers worth keeping (tracking RMS, counts), JSON-ready.
    """

    name: str
    status: Status
    summary: str
    findings: tuple[Finding, ...] = ()
    metrics: dict[str, Any] = field(default_factory=dict, hash=False)

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
class LogReport:
    """The replay of one log.

    Attributes:
        path: The log as given.
        checks: The checks run, in order.
        warnings: What was skipped or odd while reading the log.
        error: Why the log could not be replayed ("" when it could).
        wall_s: Wall time of the replay (s).
    """

    path: str
    checks: tuple[Check, ...] = ()
    warnings: tuple[str, ...] = ()
    error: str = ""
    wall_s: float = 0.0

    @property
    def status(self) -> Status:
        """ERROR when it could not be replayed, else the worst check."""
        if self.error:
            return Status.ERROR
        return Status.worst([c.status for c in self.checks])

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
            "checks": [c.to_dict() for c in self.checks],
        }


def exit_code(reports: Sequence[LogReport]) -> int:
    """Return 0 when nothing failed, 1 on any regression, 2 when a log could not be replayed."""
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
        shown = check.findings if check.status is not Status.PASS else ()
        for finding in shown[:max_findings]:
            where = f"{time_s(finding.t_ns)}: " if finding.t_ns is not None else ""
            lines.append(f"          {where}{finding.message}")
        if len(shown) > max_findings:
            lines.append(f"          ... and {len(shown) - max_findings} more")
    lines.extend(f"  warning: {warning}" for warning in report.warnings)
    return "\n".join(lines)


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
        "reports": [r.to_dict() for r in reports],
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
