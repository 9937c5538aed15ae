"""Re-synthesis beside the control loop, swapped in atomically when done.

The loop submits the newest obstacle layout and polls for finished
controllers; it never waits. In a thread (vessel, wall time) the solver runs
beside the loop (its kernels release the GIL). Inline (simulation and replay)
the solver runs at submission, so a run is deterministic for a given seed.
Only the newest pending layout is kept: a layout superseded while the solver
is busy is skipped, never queued.

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
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np
from numpy.typing import NDArray

from hil.core.samples import ObstacleLayout

FloatArray = NDArray[np.float64]

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
        controller: The new controller, or None if synthesis failed.
        error: Why it failed (None on success).
        seconds: Wall time the solver took (s), until this result.
        complete: False for an early controller (covers the submitted vessel state and
            every state of a lower value; the full one follows under the same version).
    """

    version: int
    layout: ObstacleLayout
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


StagedSolve = Callable[[ObstacleLayout, VesselState], Iterator[tuple[ControllerT, bool]]]
"""Yields (controller, complete): an early controller covering the state (if it comes
before the end), then the full one."""


class Resynthesizer(Generic[ControllerT]):
    """Runs `solve(layout)` for the newest submitted layout, off the loop's path.

    Args:
        solve: Synthesizes a controller for a layout; raises on failure (for
            example, a layout with no winning set). Exceptions become results
            with an error message, never crash the loop.
        mode: Thread or inline (see module docstring).
        stages: The same solver with an early stop (see :data:`StagedSolve`); used in a
            thread for submissions that say where the vessel is.
    """

    def __init__(
        self,
        solve: Callable[[ObstacleLayout], ControllerT],
        mode: ResynthesisMode = ResynthesisMode.THREAD,
        stages: StagedSolve[ControllerT] | None = None,
    ) -> None:
        self._solve = solve
        self._stages = stages
        self._mode = mode
        self._lock = threading.Condition()
        self._pending: ObstacleLayout | None = None
        self._pending_state: VesselState | None = None
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
        with self._lock:
            return self._busy or self._pending is not None

    def submit(self, layout: ObstacleLayout, vessel: VesselState | None = None) -> None:
        """Ask for a controller for `layout`; replaces any layout not yet started.

        With `vessel` (and a staged solver, in a thread) an early controller covering
        that state comes first.
        """
        if self._mode is ResynthesisMode.INLINE:
            self._done.append(self._run(layout, None))
            return
        with self._lock:
            if self._closed:
                raise RuntimeError("resynthesizer is closed")
            self._pending = layout
            self._pending_state = vessel
            self._lock.notify()

    def poll(self) -> SynthesisResult[ControllerT] | None:
        """Return the newest finished result since the last call, or None."""
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

    def _run(
        self, layout: ObstacleLayout, vessel: VesselState | None
    ) -> SynthesisResult[ControllerT]:
        self._version += 1
        start = time.perf_counter()
        try:
            if vessel is not None and self._stages is not None:
                controller = self._run_stages(layout, vessel, start)
            else:
                controller = self._solve(layout)
        except Exception as err:  # any solver failure is a result, not a crash
            return SynthesisResult(
                self._version,
                layout,
                None,
                f"{type(err).__name__}: {err}",
                time.perf_counter() - start,
            )
        return SynthesisResult(self._version, layout, controller, None, time.perf_counter() - start)

    def _run_stages(self, layout: ObstacleLayout, vessel: VesselState, start: float) -> ControllerT:
        """Post each early controller of a staged solve as it comes; return the full one."""
        assert self._stages is not None
        for controller, complete in self._stages(layout, vessel):
            if complete:
                return controller
            early = SynthesisResult(
                self._version, layout, controller, None, time.perf_counter() - start, False
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
                layout, self._pending = self._pending, None
                vessel, self._pending_state = self._pending_state, None
                self._busy = True
            assert layout is not None
            result = self._run(layout, vessel)
            with self._lock:
                self._done.append(result)
                self._busy = False
                self._lock.notify_all()
