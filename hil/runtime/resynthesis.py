"""Re-synthesis beside the control loop, swapped in atomically when done.

The loop submits the newest obstacle layout, with the report age its controller is
to be solved for (:mod:`hil.runtime.report_age`), and polls for finished controllers;
it never waits. In a thread (vessel, wall time) the solver runs beside the loop (its
kernels release the GIL). Inline (simulation and replay) the solver runs at
submission, so a run is deterministic for a given seed; with a stated latency its
result is handed out only that long after it started on the run's clock, one solve at
a time, as a vessel's worker thread would (a simulation of a slower solver, the same on
every machine); a layout and age solved before in the run cost nothing, as the
solver's memo makes them on the vessel. Only the newest pending layout is kept: a
layout superseded while the solver is busy is skipped, never queued.

In a thread, a solver that can stop early (``stages``) is told where the vessel
is at submission: it hands out an early controller as soon as that state is
covered (every state of a lower value final), then the full one, both under the
same version. The loop takes the early one for a decision only where it covers
the vessel's state; inline, only full controllers are made (a run stays the same
whatever the machine's speed).
"""

from __future__ import annotations

import enum
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from typing import Generic, TypeVar

from hil.core.arrays import FloatArray
from hil.core.samples import ObstacleLayout

ControllerT = TypeVar("ControllerT")


class ResynthesisMode(enum.Enum):
    """Where the solver runs."""

    THREAD = "thread"
    INLINE = "inline"


@dataclass(frozen=True, slots=True)
class SynthesisResult(Generic[ControllerT]):
    """The outcome of one synthesis.

    Attributes:
        version: 1 for the first synthesis, counting up.
        layout: The obstacle layout it was synthesized for.
        report_age_s: The report age it was solved for (s): its decisions may rely on
            `layout`'s report (or a renewal of it) while it is at most this old.
        controller: The new controller, or None if synthesis failed.
        error: Why it failed (None on success).
        seconds: Wall time the solver took (s), until this result.
        complete: False for an early controller (covers the submitted vessel state and
            every state of a lower value; the full one follows under the same version).
    """

    version: int
    layout: ObstacleLayout
    report_age_s: float
    controller: ControllerT | None
    error: str | None
    seconds: float
    complete: bool = True


@dataclass(frozen=True, slots=True)
class VesselState:
    """Where the vessel was when a layout was submitted: what an early controller covers.

    Attributes:
        eta: Estimated pose (x m, y m, psi rad), shape (3,).
        reference: Input-grid index of the reference in force.
    """

    eta: FloatArray
    reference: int


Solve = Callable[[ObstacleLayout, float], ControllerT]
"""(layout, report age in s) -> its controller; raises on failure."""
StagedSolve = Callable[[ObstacleLayout, float, VesselState], Iterator[tuple[ControllerT, bool]]]
"""(layout, report age, vessel state) -> yields (controller, complete): an early
controller covering the state (if it comes before the end), then the full one."""


@dataclass(frozen=True, slots=True)
class _Request:
    layout: ObstacleLayout
    report_age_s: float
    vessel: VesselState | None


class Resynthesizer(Generic[ControllerT]):
    """Runs `solve(layout, report_age_s)` for the newest submitted layout, off the loop's path.

    Args:
        solve: Synthesizes a controller for a layout and report age; raises on failure
            (for example, a layout with no winning set). Exceptions become results
            with an error message, never crash the loop.
        mode: Thread or inline (see module docstring).
        stages: The same solver with an early stop (see :data:`StagedSolve`); used in a
            thread for submissions that say where the vessel is.
        latency_s: Inline only: each solve takes this long on `clock` (s; 0: none).
        clock: The run's clock (ns), needed for a latency.

    Raises:
        ValueError: A negative latency, or one without a clock or in a thread.
    """

    def __init__(
        self,
        solve: Solve[ControllerT],
        mode: ResynthesisMode = ResynthesisMode.THREAD,
        stages: StagedSolve[ControllerT] | None = None,
        latency_s: float = 0.0,
        clock: Callable[[], int] | None = None,
    ) -> None:
        if not latency_s >= 0.0:
            raise ValueError(f"synthesis latency must be >= 0 s, got {latency_s!r}")
        if latency_s > 0.0 and (clock is None or mode is not ResynthesisMode.INLINE):
            raise ValueError("a synthesis latency is simulated inline only, on a clock")
        self._solve = solve
        self._stages = stages
        self._mode = mode
        self._latency_ns = round(latency_s * 1e9)
        self._clock = clock
        # Inline with a latency: results not yet handed out, each with when it is due,
        # and the (shapes, age) solved so far (solved again at once, as from the memo).
        self._running: list[tuple[int, SynthesisResult[ControllerT]]] = []
        self._seen: set[tuple[object, float]] = set()
        self._lock = threading.Condition()
        self._pending: _Request | None = None
        self._done: list[SynthesisResult[ControllerT]] = []
        self._version = 0
        self._busy = False
        self._closed = False
        self._thread: threading.Thread | None = None
        if mode is ResynthesisMode.THREAD:
            self._thread = threading.Thread(target=self._work, name="hil-resynthesis", daemon=True)
            self._thread.start()

    @property
    def busy(self) -> bool:
        """Whether a synthesis is running or waiting to run."""
        self._release()
        with self._lock:
            return self._busy or self._pending is not None or bool(self._running)

    def submit(
        self, layout: ObstacleLayout, report_age_s: float, vessel: VesselState | None = None
    ) -> None:
        """Ask for a controller for `layout`, solved for `report_age_s`.

        Replaces any layout not yet started. With `vessel` (and a staged solver, in a
        thread) an early controller covering that state comes first.
        """
        request = _Request(layout, report_age_s, vessel)
        if self._mode is ResynthesisMode.INLINE:
            if self._latency_ns == 0:
                self._done.append(self._run(request))
                return
            self._release()
            if self._running:
                self._pending = request  # the "worker" is busy: it starts when done
            else:
                assert self._clock is not None
                self._start_delayed(request, self._clock())
            return
        with self._lock:
            if self._closed:
                raise RuntimeError("resynthesizer is closed")
            self._pending = request
            self._lock.notify()

    def _start_delayed(self, request: _Request, t_ns: int) -> None:
        key = (request.layout.obstacles, request.report_age_s)
        latency_ns = 0 if key in self._seen else self._latency_ns
        self._seen.add(key)
        result = self._run(request)
        self._running.append((t_ns + latency_ns, replace(result, seconds=latency_ns / 1e9)))

    def _release(self) -> None:
        """Inline with a latency: hand out the results due by now, starting the pending one."""
        if not self._running:
            return
        assert self._clock is not None
        now = self._clock()
        while self._running and self._running[0][0] <= now:
            due, result = self._running.pop(0)
            self._done.append(result)
            if self._pending is not None:
                request, self._pending = self._pending, None
                self._start_delayed(request, due)

    def poll(self) -> SynthesisResult[ControllerT] | None:
        """Return the newest finished result since the last call, or None."""
        self._release()
        with self._lock:
            if not self._done:
                return None
            newest = self._done[-1]
            self._done.clear()
            return newest

    def wait_idle(self, timeout_s: float | None = None) -> bool:
        """Block until no synthesis is pending or running (start-up, tests)."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        with self._lock:
            while self._busy or self._pending is not None:
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    return False
                self._lock.wait(remaining)
        return True

    def close(self) -> None:
        """Stop the worker thread after the running synthesis (if any)."""
        with self._lock:
            self._closed = True
            self._lock.notify_all()
        if self._thread is not None:
            self._thread.join(timeout=30.0)

    def _run(self, request: _Request) -> SynthesisResult[ControllerT]:
        self._version += 1
        start = time.perf_counter()
        layout, age = request.layout, request.report_age_s
        try:
            if request.vessel is not None and self._stages is not None:
                controller = self._run_stages(request, start)
            else:
                controller = self._solve(layout, age)
        except Exception as err:  # any solver failure is a result, not a crash
            return SynthesisResult(
                self._version, layout, age, None, f"{type(err).__name__}: {err}",
                time.perf_counter() - start,
            )  # fmt: skip
        seconds = time.perf_counter() - start
        return SynthesisResult(self._version, layout, age, controller, None, seconds)

    def _run_stages(self, request: _Request, start: float) -> ControllerT:
        """Post each early controller of a staged solve as it comes; return the full one."""
        assert self._stages is not None
        assert request.vessel is not None
        layout, age = request.layout, request.report_age_s
        for controller, complete in self._stages(layout, age, request.vessel):
            if complete:
                return controller
            early = SynthesisResult(
                self._version, layout, age, controller, None, time.perf_counter() - start, False
            )
            with self._lock:
                self._done.append(early)
        raise RuntimeError("the staged solver ended without a full controller")

    def _work(self) -> None:
        while True:
            with self._lock:
                while self._pending is None and not self._closed:
                    self._lock.wait()
                if self._closed:
                    return
                request, self._pending = self._pending, None
                self._busy = True
            assert request is not None
            result = self._run(request)
            with self._lock:
                self._done.append(result)
                self._busy = False
                self._lock.notify_all()
