"""The real runtime driven by a scripted symbolic controller, for tests of the low level.

:class:`ScriptedController` lists one safe input per decision, the script's next row, so
the runtime's own loop (its observer, the 20-Hz low level, the simulated world) flies a
chosen reference sequence; :func:`exact_arc` is the tests' own arc of an input, written
independently of :mod:`hil.controllers.symbolic.abstraction`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic import Answer, Select
from hil.core.records import ControllerSource

F = NDArray[np.float64]
I64 = NDArray[np.int64]


class ScriptedController:
    """A symbolic controller whose only safe input at decision i is reference row i."""

    def __init__(self, refs: F) -> None:
        self._refs = refs
        self.decisions = 0
        self.source = ControllerSource.SOLVED

    @property
    def inputs(self) -> F:
        """The input grid: the reference rows, shape (n, 3)."""
        return self._refs

    def locate(self, state: F) -> int:
        """Every state is in cell 0."""
        return 0

    def nearest_input(self, velocity: F) -> int:
        """The run starts at rest on row 0's side of the script."""
        return 0

    def value(self, state: F, reference: int, first: bool) -> float:
        """One step from the target everywhere, so the loop keeps running."""
        return 1.0

    def safe_input_indices(self, state: F, reference: int, first: bool) -> I64:
        """Return the next row of the script (the last one once the script is done)."""
        i = min(self.decisions, self._refs.shape[0] - 1)
        self.decisions += 1
        return np.array([i], dtype=np.int64)

    def decide(
        self,
        state: F,
        reference: int,
        first: bool,
        previous: F,
        select: Select,
        wait_select: Select,
    ) -> Answer:
        """Fly the next row of the script, one step from the target, promising nothing.

        No contract: the runtime monitor judges no tick (no symbolic abstraction).
        """
        i = int(self.safe_input_indices(state, reference, first)[0])
        return Answer(0, 1.0, np.array([i], dtype=np.int64), False, i, None)


def exact_arc(start: F, u: F, t: F) -> tuple[F, F]:
    """Return the exact arc of u from pose `start` at times t: positions (T, 2), headings (T,).

    Complex form: pbar(t) = p0 + e^(i psi0) (u + i v) (e^(i r t) - 1) / (i r).
    """
    w = complex(u[0], u[1])
    r = float(u[2])
    z = w * t + 0j if abs(r) < 1e-12 else w * (np.exp(1j * r * t) - 1.0) / (1j * r)
    z = complex(start[0], start[1]) + np.exp(1j * start[2]) * z
    return np.stack([z.real, z.imag], axis=1), start[2] + r * t
