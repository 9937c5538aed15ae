"""One decision, asked once: the rule the vessel and the replay both take.

Given a controller, the estimated state, the reference in force, whether the decision is
a first one, the previous choice and the selection, :meth:`SymbolicAdapter.decide`
locates the cell once and returns everything the decision is: the cell, the value, the
inputs listed (safe for docking, or the safety controller's staying ones), the one
chosen and what choosing it promises (:class:`DecisionContract`). The runtime keeps the
modes, the events and the record; ``hil replay`` takes the recorded decision again with
the same call.

A selection (:data:`Select`) sees the listed inputs as :class:`Options`: their rows,
their indices, the largest value among each one's successor cells, the previous choice
and the state. The paper's cost J (:func:`j_select`) and the waiting vessel's slowest
input (:func:`wait_slowest`) are the defaults; ``hil campaign --select`` flies others
(:mod:`hil.runs.policies`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hil.controllers.symbolic.contract import DecisionContract
from hil.controllers.symbolic.controller import Controller
from hil.controllers.symbolic.selection import cheapest
from hil.core.arrays import FloatArray, IntArray
from hil.core.records import ControllerSource

__all__ = ["Answer", "Options", "Select", "SymbolicAdapter", "j_select", "wait_slowest"]


@dataclass(frozen=True, slots=True, eq=False)
class Options:
    """The inputs a decision lists, as a selection sees them.

    Attributes:
        inputs: Their rows (u m/s, v m/s, r rad/s), shape (k, 3), k >= 1.
        indices: Their input-grid indices, shape (k,).
        successor_values: The largest value among each input's successor cells, shape
            (k,): the value the next decision is at, at worst (one less than the state's
            at most, for a docking decision); -1 for the safety controller's staying
            inputs, which promise the safety set, not a value.
        previous: The previous choice, shape (3,) (zeros at a start).
        state: The estimated state (x m, y m, psi rad), shape (3,).
    """

    inputs: FloatArray
    indices: IntArray
    successor_values: IntArray
    previous: FloatArray
    state: FloatArray


Select = Callable[[Options], int]
"""Picks a row of :attr:`Options.inputs`."""


def j_select(options: Options) -> int:
    """Return the row that minimizes the paper's cost J (the first one on ties)."""
    return cheapest(options.inputs, options.previous)


def wait_slowest(options: Options) -> int:
    """Return the row a waiting vessel flies: the slowest by J against rest.

    Waiting on the safety controller (docking not winning), the vessel slows toward
    rest: J against rest (previous input zero) weighs speed with the paper's weights
    (backward and sway dearer), and the lattice keeps each change to one step.
    """
    return cheapest(options.inputs, np.zeros(3))


@dataclass(frozen=True, slots=True, eq=False)
class Answer:
    """A decision's whole answer at one state.

    Attributes:
        cell: Flat (C-order) cell index of the state, -1 outside the grid.
        value: Steps to the target (a first decision: what it earns); 0 in the target
            (hold), +inf where docking is not winning.
        inputs: Input-grid indices listed, shape (k,): every safe input for docking;
            where docking is not winning, every input that keeps the vessel in the
            safety set (`staying`); empty in the target and where nothing is safe.
        staying: Docking is not winning but the vessel can stay safe: `inputs` are the
            safety controller's, to wait on until docking wins again.
        chosen: The input-grid index flown, -1 for none (target, nothing safe).
        contract: What choosing it promises; None when nothing is chosen.
    """

    cell: int
    value: float
    inputs: IntArray
    staying: bool
    chosen: int
    contract: DecisionContract | None


class SymbolicAdapter:
    """A synthesized controller behind the runtime's ``SymbolicController`` protocol."""

    def __init__(
        self, controller: Controller, source: ControllerSource = ControllerSource.SOLVED
    ) -> None:
        self.controller = controller
        self.source = source
        """Where the controller came from (solved, the store, memory)."""
        grid = controller.grid
        self._strides = (grid.ny * grid.npsi, grid.npsi, 1)

    @property
    def inputs(self) -> FloatArray:
        """The input grid, shape (n_inputs, 3)."""
        return self.controller.inputs

    def locate(self, state: FloatArray) -> int:
        """Return the flat (C-order) cell index of `state`, -1 outside the grid."""
        cell = self.controller.grid.cell_of(state)
        if cell is None:
            return -1
        return sum(c * s for c, s in zip(cell, self._strides, strict=True))

    def nearest_input(self, velocity: FloatArray) -> int:
        """Return the input-grid index nearest a body velocity (u, v, r)."""
        return self.controller.lattice.nearest(velocity)

    def value(self, state: FloatArray, reference: int, first: bool) -> float:
        """Return the value at `state` with `reference` in force (inf: nothing safe)."""
        return self.controller.decision_value(state, reference, first)

    def safe_input_indices(self, state: FloatArray, reference: int, first: bool) -> IntArray:
        """Return the input indices of every safe input at `state`, shape (k,)."""
        cell = self.controller.grid.cell_of(state)
        if cell is None:
            return np.zeros(0, dtype=np.int64)
        return self.controller.safe_input_indices_at(cell, reference, first).astype(np.int64)

    def contract(
        self, state: FloatArray, chosen: int, reference: int, first: bool, staying: bool = False
    ) -> DecisionContract | None:
        """Return the contract of choosing `chosen` at `state` (a recorded decision's).

        None outside the grid; :meth:`decide` builds its own choice's contract.
        """
        cell = self.controller.grid.cell_of(state)
        if cell is None:
            return None
        return DecisionContract.of(self.controller, cell, chosen, reference, first, staying)

    def decide(
        self,
        state: FloatArray,
        reference: int,
        first: bool,
        previous: FloatArray,
        select: Select = j_select,
        wait_select: Select = wait_slowest,
    ) -> Answer:
        """Take the decision at `state` (3,): the cell located once, every answer in one.

        Args:
            state: The estimated state (x m, y m, psi rad).
            reference: The input-grid index in force.
            first: A first decision (start, after a stop or a hold): every candidate
                budgeted as a change, into the winning set at any value.
            previous: The previous choice (3,), for the selections that weigh changes.
            select: The choice among the safe inputs for docking.
            wait_select: The choice among the staying inputs where docking is not winning.
        """
        cell = self.controller.grid.cell_of(state)
        if cell is None:
            return Answer(-1, math.inf, np.zeros(0, dtype=np.int64), False, -1, None)
        answer = self.controller.decide_at(cell, reference, first)
        flat = sum(c * s for c, s in zip(cell, self._strides, strict=True))
        value = math.inf if answer.value < 0 else float(answer.value)
        indices = answer.inputs.astype(np.int64)
        chosen = -1
        contract = None
        if indices.size and value != 0.0:
            pick = wait_select if answer.staying else select
            options = Options(
                self.inputs[indices], indices, answer.successor_values.astype(np.int64),
                np.asarray(previous, dtype=np.float64), np.asarray(state, dtype=np.float64),
            )  # fmt: skip
            chosen = int(indices[pick(options)])
            contract = DecisionContract.of(
                self.controller, cell, chosen, reference, first, answer.staying
            )
        return Answer(flat, value, indices, answer.staying, chosen, contract)
