"""Fan a job out over an executor: the one loop behind campaigns, sweeps, replays and suites.

A :class:`Job` says how to run one specification and how to write its spec and
result as JSON; :func:`fan_out` runs every specification on an
:class:`~hil.runs.executor.Executor` and, as each run finishes, streams it to a
:class:`~hil.runs.results.ResultStream` and reports it. It promises:

- nothing finished is lost: a stop (Ctrl-C, the scheduler gone) keeps every run
  that finished, in the result and in the results file; Ctrl-C lets the runs in
  flight finish (a second Ctrl-C gives up on them);
- nothing is dropped silently: a run whose worker died is run again (up to
  `max_attempts` times); a run that raised is a :class:`Failure` with its spec;
- resumable: runs the results file already holds are read back, not run again.

At most twice the executor's capacity is in flight, so a worker always has its
next run queued and a large sweep does not flood the scheduler. An executor that
batches (Dask: a task costs milliseconds of scheduler time) gets several short runs
per call (:class:`Batch`, about :data:`BATCH_S` of work), each still streamed,
reported and failed on its own.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, wait
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

from hil.runs.executor import Executor, Warm
from hil.runs.results import ResultStream

__all__ = ["Failure", "FanOut", "Job", "fan_out"]

S = TypeVar("S")
R = TypeVar("R")

MAX_ATTEMPTS = 3
"""Runs of one specification whose worker died before it is reported failed."""
BATCH_S = 2.0
"""Work per call to a worker that batches (s), once the runs' length is known."""
MAX_BATCH = 64
"""Most runs per call."""


@dataclass(frozen=True, slots=True)
class Job(Generic[S, R]):
    """One kind of run, as the fan-out needs it (every callable picklable by reference).

    Attributes:
        name: What the runs are ("campaign", "replay", ...); names the results file's plan.
        run: Spec -> result; runs on a worker.
        encode_spec: Spec -> JSON-ready value (the plan's digest, a failure's report).
        encode_result: Result -> JSON-ready value (the results file).
        decode_result: Back from :attr:`encode_result`'s form, exactly (a resume).
        warm: Called once per worker before its first run; None for nothing.
    """

    name: str
    run: Callable[[S], R]
    encode_spec: Callable[[S], Any]
    encode_result: Callable[[R], Any]
    decode_result: Callable[[Any], R]
    warm: Warm | None = None


@dataclass(frozen=True, slots=True)
class Failure:
    """A run that did not finish, with what re-runs it alone.

    Attributes:
        index: Its place among the specifications.
        spec: Its specification, JSON-ready.
        error: Why, one line (the exception's type and message).
    """

    index: int
    spec: Any
    error: str


@dataclass(slots=True)
class FanOut(Generic[R]):
    """What a fan-out did.

    Attributes:
        results: Each specification's result, None where it did not finish.
        failures: The runs that raised (or whose workers kept dying).
        resumed: Results read back from the results file rather than run.
        retried: Runs started again because their worker died.
        stopped: Why the fan-out stopped before every run was tried ("" if it did not).
    """

    results: list[R | None]
    failures: list[Failure] = field(default_factory=list)
    resumed: int = 0
    retried: int = 0
    stopped: str = ""

    @property
    def finished(self) -> int:
        """Return how many runs have a result."""
        return sum(r is not None for r in self.results)

    @property
    def complete(self) -> bool:
        """Whether every run has a result."""
        return all(r is not None for r in self.results)


@dataclass(frozen=True, slots=True)
class Ran(Generic[R]):
    """A run that returned: its result and its wall time on the worker (s)."""

    result: R
    wall_s: float


@dataclass(frozen=True, slots=True)
class Raised:
    """A run that raised: the exception's type and message, one line."""

    error: str


Outcome = Ran[R] | Raised
"""What one run of a batch came to."""


@dataclass(frozen=True, slots=True)
class Batch(Generic[S, R]):
    """Runs several specs in one call to a worker, each run's error caught apart.

    A Dask task costs some milliseconds of scheduler and client time; batches of about
    :data:`BATCH_S` of work keep that to a few per cent of short runs, while each run
    still streams, fails and is reported on its own.

    Attributes:
        run: Spec -> result.
    """

    run: Callable[[S], R]

    def __call__(self, specs: tuple[S, ...]) -> list[Outcome[R]]:
        """Run every spec in order; return what each came to."""
        out: list[Outcome[R]] = []
        for spec in specs:
            start = time.perf_counter()
            try:
                out.append(Ran(self.run(spec), time.perf_counter() - start))
            except Exception as err:  # the run's failure, reported with its spec
                out.append(Raised(_one_line(err)))
        return out


Report = Callable[[int, Any], None]
"""Called as each run ends: its index and its result, or its :class:`Failure`."""


def _one_line(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[0]}" if text else type(err).__name__


def fan_out(job: Job[S, R], specs: Sequence[S], executor: Executor,
            stream: ResultStream | None = None, report: Report | None = None,
            max_attempts: int = MAX_ATTEMPTS) -> FanOut[R]:
    """Run `job` on every spec of `specs` (see the module docstring).

    Args:
        job: What to run.
        specs: The runs' specifications; results come back in this order.
        executor: Where to run them.
        stream: Where each finished run goes as it arrives; its runs read back on resume
            are not run again. Opened already (:meth:`ResultStream.open`).
        report: Called in this process as each run ends (a progress bar).
        max_attempts: Runs of a spec whose worker died before it is failed.
    """
    return _Fanning(job, specs, executor, stream, report, max_attempts).run()


class _Fanning(Generic[S, R]):
    """One fan-out in progress: the runs pending, in flight and finished."""

    def __init__(self, job: Job[S, R], specs: Sequence[S], executor: Executor,
                 stream: ResultStream | None, report: Report | None,
                 max_attempts: int) -> None:
        self.job, self.specs, self.executor = job, specs, executor
        self.stream, self.report, self.max_attempts = stream, report, max_attempts
        self.out: FanOut[R] = FanOut([None] * len(specs))
        if stream is not None:
            for index, data in stream.finished.items():
                self.out.results[index] = job.decode_result(data)
            self.out.resumed = len(stream.finished)
        self.pending: deque[tuple[int, int]] = deque(
            (i, 1) for i in range(len(specs)) if self.out.results[i] is None)
        self.in_flight: dict[Future[list[Outcome[R]]], list[tuple[int, int]]] = {}
        self.run_s: list[float] = []  # wall time of each finished run, as its worker measured it
        self.batch = Batch(job.run)

    def run(self) -> FanOut[R]:
        """Submit every pending run and collect the results; Ctrl-C lets those in flight end."""
        out, in_flight = self.out, self.in_flight
        try:
            while (self.pending or in_flight) and not out.stopped:
                capacity = self.executor.capacity()
                while self.pending and len(in_flight) < 2 * capacity:
                    items = self.next_batch(capacity)
                    specs = tuple(self.specs[i] for i, _ in items)
                    in_flight[self.executor.submit(self.batch, specs)] = items
                done, _ = wait(list(in_flight), return_when=FIRST_COMPLETED)
                for future in done:
                    self.settle(future, retry=True)
        except KeyboardInterrupt:
            out.stopped = "stopped by Ctrl-C"
        if in_flight:
            # No new run starts; those in flight finish (a lost cluster fails them at once).
            try:
                while in_flight:
                    done, _ = wait(list(in_flight), return_when=FIRST_COMPLETED)
                    for future in done:
                        self.settle(future, retry=False)
            except KeyboardInterrupt:
                for future in in_flight:
                    future.cancel()
        return out

    def finish(self, index: int, attempt: int, outcome: Outcome[R] | BaseException) -> None:
        """Keep one run's result or failure, stream it and report it."""
        out, stream, report = self.out, self.stream, self.report
        if isinstance(outcome, Ran):
            out.results[index] = outcome.result
            self.run_s.append(outcome.wall_s)
            if stream is not None:
                stream.record(index, self.job.encode_result(outcome.result))
            if report is not None:
                report(index, outcome.result)
            return
        why = outcome.error if isinstance(outcome, Raised) else _one_line(outcome)
        if isinstance(outcome, BaseException):
            why = f"its worker died {attempt} times (last: {why})"
        failure = Failure(index, self.job.encode_spec(self.specs[index]), why)
        out.failures.append(failure)
        if stream is not None:
            stream.record_failure(index, failure.spec, failure.error)
        if report is not None:
            report(index, failure)

    def settle(self, future: Future[list[Outcome[R]]], *, retry: bool) -> None:
        """Take a finished call in: its runs' outcomes, or its lost worker's runs again."""
        items = self.in_flight.pop(future)
        if future.cancelled():
            return  # cancelled by us: never started, not a result
        error = future.exception()
        if error is None:
            for (index, attempt), outcome in zip(items, future.result(), strict=True):
                self.finish(index, attempt, outcome)
            return
        if self.executor.cluster_lost(error):
            self.out.stopped = self.out.stopped or _one_line(error)
            return
        for index, attempt in reversed(items):
            if self.executor.worker_lost(error) and attempt < self.max_attempts:
                self.out.retried += 1
                if retry:
                    self.pending.appendleft((index, attempt + 1))
            elif self.executor.worker_lost(error):
                self.finish(index, attempt, error)
            else:  # the batch itself failed (it catches its runs' errors): report each
                self.finish(index, attempt, Raised(_one_line(error)))

    def next_batch(self, capacity: int) -> list[tuple[int, int]]:
        """Take the next runs to submit together (one unless the executor batches)."""
        size = 1
        run_s = self.run_s
        if self.executor.batches and run_s:
            # About BATCH_S of work per call, yet every worker still gets several calls.
            mean_s = max(sum(run_s[-50:]) / len(run_s[-50:]), 1e-3)
            size = max(1, min(math.ceil(BATCH_S / mean_s),
                              len(self.pending) // (2 * capacity), MAX_BATCH))
        return [self.pending.popleft() for _ in range(min(size, len(self.pending)))]
