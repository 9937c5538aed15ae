"""The reference histories the transient derivation flies, on the scenario's input grid.

Every history obeys the one-step rule of :class:`~hil.controllers.symbolic.lattice.InputLattice`
(the reference moves by at most one grid step per axis per period): randomized Euler
circuits over every (input, one-step neighbour) pair, random walks, ramps along each of
the 26 directions, and the systematic family of ramps of 1 to 4 steps into every input
with holds after them (:func:`ramp_family`).
"""

from __future__ import annotations

import itertools

import numpy as np

from hil.controllers.symbolic.lattice import InputLattice
from hil.core.arrays import FloatArray, IntArray
from hil.scenarios import Scenario

__all__ = ["RAMP_SETTLE", "InputGrid", "euler_tour", "input_grid", "ramp_family", "sweeps"]

_DIRECTIONS = np.array(
    [d for d in itertools.product((-1, 0, 1), repeat=3) if any(d)], dtype=np.int64
)  # (26, 3): the non-zero one-step moves

RAMP_SETTLE = 2
"""Holds at a ramp's first input before it starts (the path there is itself a ramp)."""


def input_grid(scenario: Scenario) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Return the scenario's input grid as (lo, hi, step), each (3,): surge, sway, yaw rate."""
    axes = (scenario.surge, scenario.sway, scenario.yaw_rate)
    lo = np.array([a.min for a in axes])
    hi = np.array([a.max for a in axes])
    step = np.array([a.step for a in axes])
    return lo, hi, step


class InputGrid:
    """The scenario's input grid in index space: inputs lo + idx * step, idx in [0, top]."""

    def __init__(self, scenario: Scenario) -> None:
        lo, hi, step = input_grid(scenario)
        self.lattice = InputLattice.of(scenario.inputs())
        """The one-step rule, as the symbolic layer defines it."""
        self.lo = lo
        self.hi = hi
        self.step = np.where(step > 0.0, step, 1.0)  # a single-value axis has one index
        self.top = np.round((hi - lo) / self.step).astype(np.int64)
        self.zero = np.clip(np.round(-lo / self.step).astype(np.int64), 0, self.top)

    def value(self, idx: IntArray) -> FloatArray:
        """Return the input (u m/s, v m/s, r rad/s) at axis indices `idx` (3,)."""
        out: FloatArray = self.lo + np.asarray(idx) * self.step
        return out

    def inputs(self) -> list[IntArray]:
        """Return the index of every input, surge slowest."""
        return [
            np.array(i, dtype=np.int64)
            for i in itertools.product(*(range(int(t) + 1) for t in self.top))
        ]

    def neighbours(self, idx: IntArray) -> IntArray:
        """Return N(idx) and idx, shape (k, 3), k <= 27, in ascending order (C order).

        The inputs that may follow idx by the lattice's one-step rule
        (:meth:`InputLattice.allowed_after`), as axis indices.
        """
        lattice = self.lattice
        sizes = [len(a) for a in lattice.axes]
        flat = (int(idx[0]) * sizes[1] + int(idx[1])) * sizes[2] + int(idx[2])
        out: IntArray = lattice.index[np.sort(lattice.allowed_after(flat))].astype(np.int64)
        return out

    def walk_step(self, idx: IntArray, rng: np.random.Generator) -> IntArray:
        """Return the next index of a walk: hold w.p. 1/3, else a uniform other neighbour."""
        if rng.random() < 1.0 / 3.0:
            return idx
        others = [n for n in self.neighbours(idx) if np.any(n != idx)]
        if not others:
            return idx
        out: IntArray = others[int(rng.integers(len(others)))]
        return out

    def walk(self, idx: IntArray, n: int, rng: np.random.Generator) -> list[IntArray]:
        """Return `n` walk indices after `idx`."""
        out = []
        for _ in range(n):
            idx = self.walk_step(idx, rng)
            out.append(idx)
        return out

    def path(self, a: IntArray, b: IntArray) -> list[IntArray]:
        """Return the indices after `a` on a shortest one-step-per-axis path to `b`."""
        out = []
        while np.any(a != b):
            a = a + np.sign(b - a)
            out.append(a)
        return out


def euler_tour(
    scenario: Scenario, rng: np.random.Generator, hold_p: float = 1.0 / 3.0
) -> FloatArray:
    """Return the references of a randomized Euler circuit over every (p, u in N(p)) pair.

    The graph has an edge p -> u for every input p and every u in N(p) (p included):
    every node has as many edges out as in (u in N(p) iff p in N(u)) and the graph is
    connected, so a circuit uses each edge once (Hierholzer, the edges of each node
    taken in random order). It starts and ends at the input nearest zero, which is not
    itself a reference: the reference before the first period. After each change the
    reference is held one more period with probability `hold_p` (a circuit alone holds
    one period in 27), so that the hold after every change is in the sample too.

    Returns:
        Shape (E + holds, 3): one reference per period, E the number of pairs.
    """
    g = InputGrid(scenario)
    nodes = g.inputs()
    flat = {tuple(int(c) for c in n): k for k, n in enumerate(nodes)}
    out_edges: list[list[int]] = []
    for n in nodes:
        succ = [flat[tuple(int(c) for c in m)] for m in g.neighbours(n)]
        rng.shuffle(succ)
        out_edges.append(succ)
    start = flat[tuple(int(c) for c in g.zero)]
    stack = [start]
    circuit: list[int] = []
    while stack:
        v = stack[-1]
        if out_edges[v]:
            stack.append(out_edges[v].pop())
        else:
            circuit.append(stack.pop())
    circuit.reverse()
    refs: list[FloatArray] = []
    for a, b in itertools.pairwise(circuit):
        refs.append(g.value(nodes[b]))
        if a != b and rng.random() < hold_p:
            refs.append(refs[-1])
    return np.array(refs)


def sweeps(g: InputGrid) -> list[IntArray]:
    """Return the indices of 26 ramps flown one after another, from the input nearest zero.

    For each direction d: a shortest path to the side of the grid the ramp starts from,
    two holds, the ramp along d until every moving axis meets the grid's edge, two holds.
    """
    idx = g.zero.copy()
    out: list[IntArray] = []
    for d in _DIRECTIONS:
        first = np.where(d > 0, 0, np.where(d < 0, g.top, idx))
        out += g.path(idx, first)
        out += [first, first]
        idx = first
        while True:
            nxt = np.clip(idx + d, 0, g.top)
            if np.all(nxt == idx):
                break
            idx = nxt
            out.append(idx)
        out += [idx, idx]
    return out


def ramp_family(
    g: InputGrid, max_steps: int, holds: int, targets: str = "all"
) -> list[list[IntArray]]:
    """Return the systematic family's reference indices, one list per target input.

    For each target u (every input, or with ``targets="edges"`` those with at least two
    axes at the grid's bounds), from the input nearest zero: for every direction d of
    the 26 with u - d on the grid and every k in 1..`max_steps` with u - k d on the
    grid, a one-step path to u - k d, :data:`RAMP_SETTLE` holds there, the k changes
    into u and `holds` holds of u.
    """
    out: list[list[IntArray]] = []
    for u in g.inputs():
        at_bound = int(np.sum((u == 0) | (u == g.top)))
        if targets == "edges" and at_bound < 2:
            continue
        idx = g.zero.copy()
        seq: list[IntArray] = []
        for d in _DIRECTIONS:
            for k in range(1, max_steps + 1):
                first = u - k * d
                if np.any(first < 0) or np.any(first > g.top):
                    break
                seq += g.path(idx, first)
                seq += [first] * RAMP_SETTLE
                seq += [u - (k - j) * d for j in range(1, k + 1)]
                seq += [u] * holds
                idx = u
        if seq:
            out.append(seq)
    return out
