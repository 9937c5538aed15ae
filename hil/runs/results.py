"""The results file of a fan-out: one JSON line per finished run, appended as it arrives.

A campaign that is stopped (Ctrl-C, a killed client, a lost scheduler) keeps every
run that finished, and ``--resume`` reads them back instead of running them again.
The file is plain JSON lines (floats as Python's ``json`` writes them, so NaN and
infinities as ``NaN`` and ``Infinity``):

- first, the header: ``{"hil_results": 1, "job": "campaign", "plan": DIGEST, "runs": N}``,
  where DIGEST hashes every run's specification, so a file is only ever resumed by
  the same campaign;
- then, per run as it finishes: ``{"run": I, "result": {...}}``, or
  ``{"run": I, "error": "...", "spec": {...}}`` for a run that failed, with its full
  specification so it can be re-run alone (a resume runs it again).

Each line is written whole and flushed; a last line cut short by a kill is dropped
(and cut from the file) when resuming.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, TextIO

from hil.runs.errors import ResultsError

__all__ = ["FORMAT", "Plan", "ResultStream"]

FORMAT = 1
"""Version of the file's layout (the header's ``hil_results``)."""


@dataclass(frozen=True, slots=True)
class Plan:
    """What a results file belongs to.

    Attributes:
        job: The kind of runs ("campaign", "sweep", "replay").
        digest: SHA-256 (hex, 16 digits) over every run's specification, in order.
        runs: Number of runs planned.
    """

    job: str
    digest: str
    runs: int

    @staticmethod
    def of(job: str, specs: Iterable[Any]) -> Plan:
        """Return the plan of JSON-ready run specifications `specs`."""
        digest = hashlib.sha256(job.encode())
        count = 0
        for spec in specs:
            digest.update(json.dumps(spec, sort_keys=True).encode())
            digest.update(b"\n")
            count += 1
        return Plan(job, digest.hexdigest()[:16], count)

    def header(self) -> dict[str, Any]:
        """Return the header line's object."""
        return {"hil_results": FORMAT, "job": self.job, "plan": self.digest, "runs": self.runs}


class ResultStream:
    """Appends finished runs to a results file; on resume, first reads back those it holds.

    Args:
        path: The results file.
        plan: The runs it is for.
        resume: Continue an existing file of the same plan (a missing one is started);
            False refuses an existing, non-empty file rather than overwrite it.
    """

    def __init__(self, path: Path, plan: Plan, *, resume: bool = False) -> None:
        self.path = path
        self.plan = plan
        self.resume = resume
        self.finished: dict[int, Any] = {}
        """Results read back on resume, by run index (JSON-ready form)."""
        self.dropped_partial = False
        """Whether resuming cut off a last line that a kill left unfinished."""
        self._file: TextIO | None = None

    def open(self) -> ResultStream:
        """Open the file: read back its runs (resume) or start it with the header.

        Raises:
            ResultsError: It exists and `resume` is False, or it belongs to another
                plan, or is no results file, or cannot be written.
        """
        try:
            exists = self.path.is_file() and self.path.stat().st_size > 0
            if exists and not self.resume:
                raise ResultsError(
                    f"results file {str(self.path)!r} exists: pass --resume to continue it, "
                    "or remove it")
            if exists:
                self._read_back()
                self._file = self.path.open("a", encoding="utf-8")
            else:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                self._file = self.path.open("w", encoding="utf-8")
                self._write(self.plan.header())
        except OSError as err:
            raise ResultsError(f"cannot write results file {str(self.path)!r}: {err}") from err
        return self

    def _read_back(self) -> None:
        data = self.path.read_bytes()
        end = data.rfind(b"\n") + 1
        if end < len(data):  # a line a kill cut short: drop it, or the next append joins it
            self.dropped_partial = True
            with self.path.open("r+b") as f:
                f.truncate(end)
            data = data[:end]
        lines = data.decode("utf-8").splitlines()
        try:
            header = json.loads(lines[0]) if lines else {}
        except ValueError:
            header = {}
        where = repr(str(self.path))
        if not isinstance(header, dict) or header.get("hil_results") != FORMAT:
            raise ResultsError(f"{where} is no hil results file (no header line)")
        if header != self.plan.header():
            raise ResultsError(
                f"{where} holds another {header.get('job')!r} of {header.get('runs')} runs "
                f"(plan {header.get('plan')}), not this {self.plan.job!r} of {self.plan.runs} "
                f"(plan {self.plan.digest}): same arguments to resume, or another file")
        for number, line in enumerate(lines[1:], start=2):
            try:
                entry = json.loads(line)
                index = int(entry["run"])
            except (ValueError, KeyError, TypeError) as err:
                raise ResultsError(f"{where} line {number} is unreadable: {err}") from err
            if "result" in entry and 0 <= index < self.plan.runs:
                self.finished[index] = entry["result"]

    def record(self, index: int, result: Any) -> None:
        """Append run `index`'s result (JSON-ready) and flush."""
        self._write({"run": index, "result": result})

    def record_failure(self, index: int, spec: Any, error: str) -> None:
        """Append run `index`'s failure with its specification (JSON-ready) and flush."""
        self._write({"run": index, "error": error, "spec": spec})

    def _write(self, entry: dict[str, Any]) -> None:
        if self._file is None:
            raise ResultsError(f"results file {str(self.path)!r} is not open")
        # One write of the whole line: a kill leaves a whole line or a cut last one.
        self._file.write(json.dumps(entry, sort_keys=True) + "\n")
        self._file.flush()

    def close(self) -> None:
        """Close the file."""
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> ResultStream:
        return self if self._file is not None else self.open()

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()
