"""The transient budget the shipped low level achieves, derived from the code it runs.

A scenario's ``[transient]`` (:class:`~hil.core.transient.TransientBudget`) bounds, per
class of command period and time bin, how far the true pose strays from the exact arc
of the commanded input u started at the true pose at the period's start: the position
``|p(t) - pbar(t)|`` and heading ``|psi(t) - psibar(t)|`` for every t up to the bin's
end. The classes (:class:`~hil.core.transient.BudgetClass`): *hold* (the reference
equals the previous period's), *change* (it moved by at most one input-grid step per
axis) and *start* (the first period of a run). It is measured here on the compiled
closed loop of :mod:`hil.sim.closed_loop` (the runtime's low-level tick at 20 Hz on the
simulated plant, sensors and EKF in the loop), on references that obey the game's rule:
each period the reference stays or moves to a neighbour on the scenario's input grid.

Each period lasts a random whole number of physics steps in [tau, tau + LATE_S]
(uniform): a command may be held up to two 20-Hz ticks late. The references are fed to
the closed loop per physics step, so a period may begin between two low-level ticks;
the low level picks the new reference up at its next tick, as on the vessel. The bins
cover tau + LATE_S (9 of 0.25 s for tau = 2 s), and every period is measured to its end.

The references (:class:`TransientRecipe`):

- *tours*, from rest at the input nearest zero: randomized Euler circuits of the graph
  whose edges are every pair (p, u in N(p)), N(p) the up to 27 inputs within one step
  per axis (holds included): each tour flies every pair exactly once, each preceded by
  the random history the circuit took into p (a change into p 26 times in 27), and
  after a change holds one more period with probability 1/3, so that the tails of
  every change are in both classes' sample;
- *walks*, from rest: long random walks, each period a hold with probability 1/3, else
  a uniformly chosen other neighbour;
- *sweeps*, from rest: for each of the 26 directions a ramp of changes along it from
  one side of the grid to the other, then holds (the low level lags a ramp most);
- *ramps*, the systematic family (one run per target input u, from rest): for every
  one-step direction d into u (u - d on the grid) and every ramp length k of 1 to
  ``ramp_steps`` (u - k d on the grid), a one-step path to u - k d, ``RAMP_SETTLE`` holds
  there, k changes along d into u, then ``ramp_holds`` holds of u. Every corner, edge,
  face and interior input of the lattice is a target (``ramp_targets = "all"``; "edges"
  keeps the inputs with at least two axes at the box's bounds, where the thrusters
  saturate). Holds converge within two periods of the last change (measured per
  consecutive hold: :attr:`Measured.hold_streak_position_m`), so ``ramp_holds`` = 4
  reaches the steady hold and longer ramps add nothing after 3-4 steps;
- *starts* (class start), for every pair (p*, u in N(p*)): the true velocity drawn
  uniformly within half a grid step of p* per axis (clipped to the input box),
  thrusters idle, a random heading, the EKF from the true state as configured, the
  first reference u, then a walk; once more from the corner of that half-step box
  farthest from u (the largest first step the rule allows), u then held; and from rest
  exactly (p* the input nearest zero) to every u in N(p*).

Every period is classified (:func:`classify`), and per class and bin the largest
deviation over all periods (a running max over the bins) is multiplied by
``safety_factor``, increased by ``position_margin_m`` / ``heading_margin_rad`` and
rounded up to ``DIGITS`` decimals. The velocity envelopes (max ``|nu - nu_ref|`` per
class, bin and axis, both bin edges) and the estimation bounds (the largest EKF
position and heading errors of every run after its first ``estimation_after_s``) are
scaled by ``safety_factor`` and rounded alike. :func:`check_bound` flies a recipe on
other seeds and compares what it measures with a budget.

The family's own maxima per class and bin (:attr:`Measured.family_position_m`,
:attr:`Measured.family_heading_rad`) are kept beside the overall ones, and
:meth:`TransientDerivation.family_factors` gives the factor the budget keeps over them
(>= 1 everywhere, by construction for the derivation's seeds; a test flies the family on
other seeds and fails on any factor < 1).

``python -m bench lowlevel`` prints the table; tests/sim/test_transient_derivation.py checks that
the packaged scenarios ship it and that fresh runs stay inside it.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, replace

import numpy as np

from hil.controllers.symbolic.abstraction import displacement
from hil.controllers.symbolic.lattice import InputLattice
from hil.core.arrays import FloatArray, IntArray
from hil.core.geometry import wrap_angles
from hil.core.transient import (
    LATE_S,
    N_CLASSES,
    START_PERIODS,
    BudgetClass,
    TransientBudget,
    horizon_bins,
)
from hil.scenarios import Scenario
from hil.sim.closed_loop import ClosedLoopResult, LowLevelConfig, simulate_closed_loop
from hil.sim.errors import ClosedLoopConfigError

__all__ = [
    "CLASS_NAMES",
    "DIGITS",
    "RAMP_SETTLE",
    "BoundRatios",
    "Measured",
    "Run",
    "TransientDerivation",
    "TransientRecipe",
    "check_bound",
    "classify",
    "derive_transient",
    "euler_tour",
    "fly",
    "hold_streaks",
    "input_grid",
    "measure",
    "period_steps",
    "ramp_family",
    "recipe_runs",
    "round_up",
    "toml_table",
]

DIGITS = 4
"""Decimals of the ``[transient]`` entries (m/s, m/s, rad/s, m, rad)."""

CLASS_NAMES = ("hold", "change", "start")
"""The classes' names, by :class:`~hil.core.transient.BudgetClass` (the TOML key prefixes)."""

_AXES = ("surge_mps", "sway_mps", "yaw_rate_radps")

_DIRECTIONS = np.array(
    [d for d in itertools.product((-1, 0, 1), repeat=3) if any(d)], dtype=np.int64
)  # (26, 3): the non-zero one-step moves

RAMP_SETTLE = 2
"""Holds at a ramp's first input before it starts (the path there is itself a ramp)."""


@dataclass(frozen=True, slots=True)
class TransientRecipe:
    """How the transient budget is measured (the default: ~100 s on one core, 186,000 s flown).

    Attributes:
        tours: Randomized Euler tours over every (p, u in N(p)) pair, one run each.
        walks: Long random walks from rest, one run each.
        walk_s: Length of each walk (s).
        sweeps: Whether to fly the 26 ramps (one run).
        ramps: Passes over the systematic family (0: none), one run per target each.
        ramp_steps: Longest ramp of the family (changes along one direction).
        ramp_holds: Holds of the target after each ramp of the family.
        ramp_targets: ``all`` inputs or only the lattice's ``edges`` (and corners).
        starts: Passes over every (p*, u in N(p*)) pair starting moving, one run each;
            each pass also starts once from rest to every u in N(p*), p* the input
            nearest zero.
        start_corners: Whether to add, for every pair, a start at the corner of the
            half-step box around p* farthest from u, then u held.
        start_share: Share of the pairs each start pass flies (drawn at random; 1: every
            pair), for quick checks.
        start_periods: Periods of each start run (the first START_PERIODS are of class
            start, the one after them shows what a start leaves to a hold or change).
        bin_s: Width of the time bins (s); as many bins as cover tau + LATE_S.
        safety_factor: Factor on every measured maximum.
        position_margin_m: Added to each scaled position deviation (m).
        heading_margin_rad: Added to each scaled heading deviation (rad).
        estimation_after_s: The EKF's errors count from this far into each run (s): the
            runtime's first decision waits this long for the filter
            (``LoopConfig.observer_settle_s``; a test keeps them equal).
        estimation_factor: Factor on the EKF's measured errors: their tail is long (a
            1,000-run campaign met 2.6 mm against 1.7 mm measured here).
        seed: Seed of the references, period lengths, starts and sensor noise (a
            derivation is a deterministic function of the recipe).
    """

    tours: int = 2
    walks: int = 4
    walk_s: float = 180.0
    sweeps: bool = True
    ramps: int = 1
    ramp_steps: int = 4
    ramp_holds: int = 4
    ramp_targets: str = "all"
    starts: int = 1
    start_corners: bool = True
    start_share: float = 1.0
    start_periods: int = START_PERIODS + 1
    bin_s: float = 0.25
    safety_factor: float = 1.25
    position_margin_m: float = 0.002
    heading_margin_rad: float = 0.002
    estimation_after_s: float = 1.0
    estimation_factor: float = 2.0
    seed: int = 2000

    def describe(self) -> str:
        """Return the one-line source text a scenario stores with its budget."""
        share = "all" if self.start_share >= 1.0 else f"{self.start_share:g} of the"
        return (
            "hil.sim.transient (python -m bench lowlevel): max deviation from the exact arc "
            f"(|p - pbar|, |psi - psibar|) per class and {self.bin_s:g}-s bin, running max, "
            f"x{self.safety_factor:g} + {self.position_margin_m:g} m / "
            f"{self.heading_margin_rad:g} rad; max |nu - nu_ref| x{self.safety_factor:g}; "
            f"EKF pose error after {self.estimation_after_s:g} s x{self.estimation_factor:g}; "
            f"rounded up to 1e-{DIGITS}; periods of tau to tau + {LATE_S:g} s (uniform, "
            f"whole physics steps); {self.tours} Euler tours of all (p, u in N(p)) pairs, "
            f"{self.walks} walks x {self.walk_s:g} s, {'26 ramps, ' if self.sweeps else ''}"
            f"{self._family()}"
            f"starts from {self.starts}"
            f"{' + 1 (farthest corner)' if self.start_corners else ''} x {share} pairs "
            f"and from rest, {self.start_periods} periods each; seed {self.seed}; the "
            "runtime's low level on the simulated plant, sensors and EKF"
        )

    def _family(self) -> str:
        if self.ramps <= 0:
            return ""
        return (
            f"{self.ramps} x the family (every one-step direction into {self.ramp_targets} "
            f"inputs, ramps of 1-{self.ramp_steps} steps, {self.ramp_holds} holds after), "
        )

    def __post_init__(self) -> None:
        if self.ramp_targets not in ("all", "edges"):
            raise ClosedLoopConfigError(
                f"ramp_targets must be 'all' or 'edges', got {self.ramp_targets!r}"
            )
        if self.ramp_steps < 1 or self.ramp_holds < 1:
            raise ClosedLoopConfigError(
                f"ramp_steps and ramp_holds must be >= 1, got {self.ramp_steps}, {self.ramp_holds}"
            )


@dataclass(frozen=True, slots=True, eq=False)
class Run:
    """One closed-loop run of the recipe: its references, period lengths and start.

    Attributes:
        kind: ``tour``, ``walk``, ``sweeps``, ``ramps`` (the systematic family), ``start``
            (moving), ``corner`` or ``rest``.
        refs: References, shape (N, 3) (m/s, m/s, rad/s), one per period.
        steps: Length of each period in physics steps, shape (N,).
        previous: p*, the input the run starts near, shape (3,): the input nearest zero
            from rest; the first reference is in N(p*).
        nu0: Initial true velocity, shape (3,).
        eta0: Initial pose, shape (3,) (m, m, rad).
        seed: Sensor-noise seed.
    """

    kind: str
    refs: FloatArray
    steps: IntArray
    previous: FloatArray
    nu0: FloatArray
    eta0: FloatArray
    seed: int

    def step_refs(self) -> FloatArray:
        """Return the reference at every physics step, shape (sum(steps), 3)."""
        out: FloatArray = np.repeat(self.refs, self.steps, axis=0)
        return out

    def starts(self) -> IntArray:
        """Return the physics step each period begins at, shape (N,)."""
        out: IntArray = np.concatenate(([0], np.cumsum(self.steps)[:-1])).astype(np.int64)
        return out


@dataclass(frozen=True, slots=True)
class Measured:
    """The largest deviations a set of runs showed, per class.

    Attributes:
        envelopes: Max |nu - nu_ref| per [class, bin, axis], shape (3, n_bins, 3).
        position_m: Max |p - pbar| over t <= each bin's end, shape (3, n_bins) (m).
        heading_rad: Max |psi - psibar| likewise, shape (3, n_bins) (rad).
        estimation: Max EKF errors (position m, heading rad), shape (2,).
        periods: Periods per class, shape (3,).
        samples: Physics samples per class, shape (3,).
        simulated_s: Simulated time (s).
        family_position_m: Max |p - pbar| over the systematic family's periods alone,
            shape (3, n_bins) (m); zero where the recipe flies no family.
        family_heading_rad: Max |psi - psibar| likewise, shape (3, n_bins) (rad).
        family_periods: The family's periods per class, shape (3,).
        hold_streak_position_m: Max |p - pbar| of hold periods by how many holds in a
            row they are (row h: the (h + 1)-th hold since the last change or start; the
            last row: that many or more), shape (ramp_holds, n_bins) (m): how fast a hold
            after changes settles to the steady hold.
    """

    envelopes: FloatArray
    position_m: FloatArray
    heading_rad: FloatArray
    estimation: FloatArray
    periods: IntArray
    samples: IntArray
    simulated_s: float
    family_position_m: FloatArray
    family_heading_rad: FloatArray
    family_periods: IntArray
    hold_streak_position_m: FloatArray


@dataclass(frozen=True, slots=True)
class BoundRatios:
    """Measured deviations over a budget's bounds, per class.

    Attributes:
        position: Max over bins of measured |p - pbar| / position_m, shape (3,).
        heading: Max over bins of measured |psi - psibar| / heading_rad, shape (3,).
        position_m: Largest |p - pbar| (m) per class, shape (3,).
        heading_rad: Largest |psi - psibar| (rad) per class, shape (3,).
        periods: Periods judged per class, shape (3,).
    """

    position: FloatArray
    heading: FloatArray
    position_m: FloatArray
    heading_rad: FloatArray
    periods: IntArray

    @property
    def worst(self) -> float:
        """Return the largest ratio of all (< 1: every period inside its bound)."""
        return float(max(self.position.max(), self.heading.max()))


@dataclass(frozen=True, slots=True)
class TransientDerivation:
    """What a derivation measured and the budget it makes.

    Attributes:
        budget: The scenario's ``[transient]``: measured maxima scaled, rounded up.
        measured: The measured maxima.
        ratios: The measured maxima over the budget (the margin it leaves, per class).
        seconds: Wall time of the derivation (s).
    """

    budget: TransientBudget
    measured: Measured
    ratios: BoundRatios
    seconds: float

    def family_factors(self) -> tuple[FloatArray, FloatArray]:
        """Return the factor the budget keeps over the systematic family, per class and bin.

        Returns:
            (position, heading), each shape (3, n_bins): budget / the family's measured
            maximum; inf where the family measured nothing (no period of that class, or
            a deviation of 0).
        """
        return (
            _factors(self.budget.position_m, self.measured.family_position_m),
            _factors(self.budget.heading_rad, self.measured.family_heading_rad),
        )


def _factors(bound: FloatArray, measured: FloatArray) -> FloatArray:
    with np.errstate(divide="ignore", invalid="ignore"):
        out: FloatArray = np.where(measured > 0.0, bound / measured, np.inf)
    return out


def input_grid(scenario: Scenario) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Return the scenario's input grid as (lo, hi, step), each (3,): surge, sway, yaw rate."""
    axes = (scenario.surge, scenario.sway, scenario.yaw_rate)
    lo = np.array([a.min for a in axes])
    hi = np.array([a.max for a in axes])
    step = np.array([a.step for a in axes])
    return lo, hi, step


def round_up(values: FloatArray, digits: int = DIGITS) -> FloatArray:
    """Return `values` rounded up to `digits` decimals (same shape)."""
    scale = 10.0**digits
    out: FloatArray = np.ceil(np.asarray(values, dtype=np.float64) * scale - 1e-9) / scale
    return out


class _Grid:
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
    g = _Grid(scenario)
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


def _sweeps(g: _Grid) -> list[IntArray]:
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


def ramp_family(g: _Grid, max_steps: int, holds: int, targets: str = "all") -> list[list[IntArray]]:
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


def period_steps(scenario: Scenario, dt_s: float) -> tuple[int, int]:
    """Return the fewest and most physics steps of a period: tau and tau + LATE_S.

    Raises:
        ClosedLoopConfigError: tau is not a whole number of physics steps.
    """
    ratio = scenario.tau_s / dt_s
    if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
        raise ClosedLoopConfigError(
            f"tau_s={scenario.tau_s!r} is not a whole number of physics steps dt_s={dt_s!r}"
        )
    return round(ratio), round(ratio) + math.floor(LATE_S / dt_s + 1e-9)


def recipe_runs(scenario: Scenario, recipe: TransientRecipe, dt_s: float = 0.01) -> list[Run]:
    """Return the runs of `recipe` on `scenario`'s input grid (deterministic in the seed).

    Args:
        scenario: Its input grid and period.
        recipe: What to fly.
        dt_s: The physics step the period lengths are whole numbers of (s).
    """
    g = _Grid(scenario)
    rng = np.random.default_rng(recipe.seed)
    lengths = np.random.default_rng([recipe.seed, 1])
    lo_steps, hi_steps = period_steps(scenario, dt_s)
    rest = g.value(g.zero)
    zeros = np.zeros(3)
    seeds = itertools.count(recipe.seed)
    runs: list[Run] = []

    def add(
        kind: str, refs: FloatArray, previous: FloatArray, nu0: FloatArray, psi0: float
    ) -> None:
        steps: IntArray = np.asarray(
            lengths.integers(lo_steps, hi_steps + 1, size=refs.shape[0]), dtype=np.int64
        )
        eta0 = np.array([0.0, 0.0, psi0])
        runs.append(Run(kind, refs, steps, previous, nu0, eta0, next(seeds)))

    for _ in range(recipe.tours):
        add("tour", euler_tour(scenario, rng), rest, zeros, 0.0)
    n_walk = max(1, round(recipe.walk_s / scenario.tau_s))
    for _ in range(recipe.walks):
        add("walk", np.array([g.value(i) for i in g.walk(g.zero, n_walk, rng)]), rest, zeros, 0.0)
    if recipe.sweeps:
        add("sweeps", np.array([g.value(i) for i in _sweeps(g)]), rest, zeros, 0.0)
    for _ in range(recipe.ramps):
        for seq in ramp_family(g, recipe.ramp_steps, recipe.ramp_holds, recipe.ramp_targets):
            add("ramps", np.array([g.value(i) for i in seq]), rest, zeros, 0.0)
    pairs = [(p, u) for p in g.inputs() for u in g.neighbours(p)]
    n_pairs = round(recipe.start_share * len(pairs))

    def some_pairs() -> list[tuple[IntArray, IntArray]]:
        if n_pairs >= len(pairs):
            return pairs
        return [pairs[k] for k in sorted(rng.choice(len(pairs), n_pairs, replace=False))]

    def heading() -> float:
        return float(rng.uniform(-math.pi, math.pi))

    for _ in range(recipe.starts):
        for star, first in some_pairs():
            p_star = g.value(star)
            nu0 = np.clip(p_star + rng.uniform(-0.5, 0.5, 3) * g.step, g.lo, g.hi)
            idx = [first, *g.walk(first, recipe.start_periods - 1, rng)]
            add("start", np.array([g.value(i) for i in idx]), p_star, nu0, heading())
        for first in g.neighbours(g.zero):
            idx = [first, *g.walk(first, recipe.start_periods - 1, rng)]
            add("rest", np.array([g.value(i) for i in idx]), rest, zeros, heading())
    if recipe.start_corners:
        for star, first in some_pairs():
            p_star = g.value(star)
            away = np.sign(first - star).astype(np.float64)
            away[away == 0.0] = rng.choice((-1.0, 1.0), size=int(np.sum(away == 0.0)))
            nu0 = np.clip(p_star - 0.5 * away * g.step, g.lo, g.hi)
            refs = np.repeat(g.value(first)[None, :], recipe.start_periods, axis=0)
            add("corner", refs, p_star, nu0, heading())
    return runs


def classify(run: Run) -> IntArray:
    """Return the budget class of each period of `run`, shape (N,).

    The first :data:`~hil.core.transient.START_PERIODS` periods are a start (2); after
    them a period holds (0) when its reference equals the one before, else it changes (1).
    """
    prev = run.refs[:-1]
    out = np.full(run.refs.shape[0], BudgetClass.START, dtype=np.int64)
    same = np.all(run.refs[1:] == prev, axis=1)
    out[1:] = np.where(same, BudgetClass.HOLD, BudgetClass.CHANGE)
    out[:START_PERIODS] = BudgetClass.START
    return out


def hold_streaks(run: Run) -> IntArray:
    """Return, per period of `run`, how many holds in a row end at it, shape (N,).

    0 for a change or a start period; 1 for the first hold after a change (or after
    the start), 2 for the second, and so on.
    """
    classes = classify(run)
    out = np.zeros(classes.shape[0], dtype=np.int64)
    for n in range(classes.shape[0]):
        if classes[n] == BudgetClass.HOLD:
            out[n] = (out[n - 1] if n else 0) + 1
    return out


def fly(run: Run, config: LowLevelConfig) -> ClosedLoopResult:
    """Fly `run` on the closed loop of `config` (its low level, physics and observer).

    The references are fed per physics step (``command_period_s = dt_s``), so a period
    may begin between two low-level ticks; the low level still ticks every
    ``control_period_s`` and reads the reference then, as on the vessel.
    """
    cfg = replace(config, command_period_s=config.dt_s, seed=run.seed)
    return simulate_closed_loop(run.step_refs(), cfg, run.eta0, run.nu0)


@dataclass(frozen=True, slots=True)
class _Periods:
    """One run cut into periods, reduced to bins.

    Attributes:
        classes: (N,) budget classes.
        envelopes: (N, n_bins, 3) max |nu - nu_ref| per bin and axis (both edges).
        position: (N, n_bins) max |p - pbar| up to each bin's end (m).
        heading: (N, n_bins) max |psi - psibar| up to each bin's end (rad).
        samples: (N,) physics samples of each period (its closing sample, the next
            period's first, included; missing for a run's last period).
        estimation: (2,) max EKF position (m) and heading (rad) errors after the start.
    """

    classes: IntArray
    envelopes: FloatArray
    position: FloatArray
    heading: FloatArray
    samples: IntArray
    estimation: FloatArray


def _periods(
    run: Run, res: ClosedLoopResult, dt_s: float, bin_s: float, n_bins: int, after_s: float
) -> _Periods:
    n = run.refs.shape[0]
    steps = run.steps
    longest = int(steps.max())
    total = res.t_s.shape[0]
    k = np.arange(longest + 1)
    t: FloatArray = k.astype(np.float64) * dt_s
    idx = run.starts()[:, None] + k[None, :]
    valid = (k[None, :] <= steps[:, None]) & (idx < total)
    idx = np.minimum(idx, total - 1)
    error = np.abs(res.nu[idx] - run.refs[:, None, :])
    error[~valid] = 0.0
    eps = 1e-9 * max(1.0, bin_s)
    envelopes = np.zeros((n, n_bins, 3))
    ends = np.zeros(n_bins, dtype=np.int64)
    for j in range(n_bins):
        inside = np.nonzero((t >= j * bin_s - eps) & (t <= (j + 1) * bin_s + eps))[0]
        if inside.size:
            envelopes[:, j] = error[:, inside[0] : inside[-1] + 1].max(axis=1)
        ends[j] = np.nonzero(t <= (j + 1) * bin_s + eps)[0][-1]
    start = res.eta[run.starts()]  # (N, 3) true pose at each period's start
    d = displacement(run.refs, t)  # (N, S + 1, 2) in the start body frame
    c, s = np.cos(start[:, 2])[:, None], np.sin(start[:, 2])[:, None]
    pbar_x = start[:, 0:1] + c * d[..., 0] - s * d[..., 1]
    pbar_y = start[:, 1:2] + s * d[..., 0] + c * d[..., 1]
    pos = res.eta[idx]
    dev_p = np.where(valid, np.hypot(pos[..., 0] - pbar_x, pos[..., 1] - pbar_y), 0.0)
    psibar = start[:, 2:3] + run.refs[:, 2:3] * t[None, :]
    dev_psi = np.where(valid, np.abs(wrap_angles(pos[..., 2] - psibar)), 0.0)
    late = res.t_s >= after_s - 1e-9
    est = np.zeros(2)
    if np.any(late):
        est[0] = np.max(np.hypot(*(res.eta_hat[late, :2] - res.eta[late, :2]).T))
        est[1] = np.max(np.abs(wrap_angles(res.eta_hat[late, 2] - res.eta[late, 2])))
    return _Periods(
        classes=classify(run),
        envelopes=envelopes,
        position=np.maximum.accumulate(dev_p, axis=1)[:, ends],
        heading=np.maximum.accumulate(dev_psi, axis=1)[:, ends],
        samples=valid.sum(axis=1),
        estimation=est,
    )


def measure(
    scenario: Scenario,
    recipe: TransientRecipe,
    config: LowLevelConfig | None = None,
    bin_s: float | None = None,
) -> Measured:
    """Fly every run of `recipe` and return the largest deviations per class and bin.

    Args:
        scenario: Its input grid and period.
        recipe: What to fly.
        config: The low level (default: the vessel's); its ``command_period_s`` is not
            used (the references are fed per physics step).
        bin_s: Bin width (s); default the recipe's. As many bins as cover tau + LATE_S.

    Raises:
        ClosedLoopConfigError: tau is not a whole number of physics steps.
    """
    cfg = LowLevelConfig() if config is None else config
    width = recipe.bin_s if bin_s is None else bin_s
    n_bins = horizon_bins(scenario.tau_s, width)
    env = np.zeros((N_CLASSES, n_bins, 3))
    position = np.zeros((N_CLASSES, n_bins))
    heading = np.zeros((N_CLASSES, n_bins))
    family_position = np.zeros((N_CLASSES, n_bins))
    family_heading = np.zeros((N_CLASSES, n_bins))
    streaks = np.zeros((recipe.ramp_holds, n_bins))
    est = np.zeros(2)
    counts = np.zeros(N_CLASSES, dtype=np.int64)
    family_counts = np.zeros(N_CLASSES, dtype=np.int64)
    samples = np.zeros(N_CLASSES, dtype=np.int64)
    simulated = 0.0
    for run in recipe_runs(scenario, recipe, cfg.dt_s):
        res = fly(run, cfg)
        p = _periods(run, res, cfg.dt_s, width, n_bins, recipe.estimation_after_s)
        simulated += float(run.steps.sum()) * cfg.dt_s
        est = np.maximum(est, p.estimation)
        streak = np.minimum(hold_streaks(run), recipe.ramp_holds)
        for h in range(1, recipe.ramp_holds + 1):
            rows = streak == h
            if np.any(rows):
                streaks[h - 1] = np.maximum(streaks[h - 1], p.position[rows].max(axis=0))
        for cls in range(N_CLASSES):
            rows = p.classes == cls
            if not np.any(rows):
                continue
            counts[cls] += int(rows.sum())
            samples[cls] += int(p.samples[rows].sum())
            env[cls] = np.maximum(env[cls], p.envelopes[rows].max(axis=0))
            position[cls] = np.maximum(position[cls], p.position[rows].max(axis=0))
            heading[cls] = np.maximum(heading[cls], p.heading[rows].max(axis=0))
            if run.kind == "ramps":
                family_counts[cls] += int(rows.sum())
                family_position[cls] = np.maximum(
                    family_position[cls], p.position[rows].max(axis=0)
                )
                family_heading[cls] = np.maximum(family_heading[cls], p.heading[rows].max(axis=0))
    return Measured(
        env,
        position,
        heading,
        est,
        counts,
        samples,
        simulated,
        family_position,
        family_heading,
        family_counts,
        streaks,
    )


def _ratios(budget: TransientBudget, measured: Measured) -> BoundRatios:
    """Return `measured` over `budget`'s bounds per class (a deviation over 0 counts inf)."""
    return BoundRatios(
        position=_worst_ratio(measured.position_m, budget.position_m),
        heading=_worst_ratio(measured.heading_rad, budget.heading_rad),
        position_m=measured.position_m.max(axis=1),
        heading_rad=measured.heading_rad.max(axis=1),
        periods=measured.periods,
    )


def _worst_ratio(dev: FloatArray, bound: FloatArray) -> FloatArray:
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(bound > 0.0, dev / bound, np.where(dev > 0.0, np.inf, 0.0))
    out: FloatArray = ratio.max(axis=1)
    return out


def derive_transient(
    scenario: Scenario,
    recipe: TransientRecipe | None = None,
    config: LowLevelConfig | None = None,
) -> TransientDerivation:
    """Measure the transient budget the shipped low level achieves on `scenario`'s inputs.

    Args:
        scenario: Its input grid and command period ``tau_s`` are used.
        recipe: How to measure (default: :class:`TransientRecipe`).
        config: The low level (default: the vessel's).

    Returns:
        The budget (deviations x safety factor + margin, envelopes and estimation x
        safety factor, all rounded up to ``DIGITS``), the raw maxima and their ratio to
        the budget.
    """
    rec = TransientRecipe() if recipe is None else recipe
    t0 = time.perf_counter()
    m = measure(scenario, rec, config)
    f = rec.safety_factor
    budget = TransientBudget(
        bin_s=rec.bin_s,
        envelopes=round_up(m.envelopes * f),
        position_m=round_up(m.position_m * f + rec.position_margin_m),
        heading_rad=round_up(m.heading_rad * f + rec.heading_margin_rad),
        estimation_position_m=float(round_up(m.estimation[0] * rec.estimation_factor)),
        estimation_heading_rad=float(round_up(m.estimation[1] * rec.estimation_factor)),
        source=rec.describe(),
    )
    return TransientDerivation(
        budget=budget,
        measured=m,
        ratios=_ratios(budget, m),
        seconds=time.perf_counter() - t0,
    )


def check_bound(
    scenario: Scenario,
    budget: TransientBudget,
    recipe: TransientRecipe,
    config: LowLevelConfig | None = None,
) -> BoundRatios:
    """Fly `recipe` (fresh seeds: choose its ``seed``) and judge every period by `budget`."""
    return _ratios(budget, measure(scenario, recipe, config, bin_s=budget.bin_s))


def toml_table(budget: TransientBudget) -> str:
    """Return `budget` as the scenario's ``[transient]`` TOML table (no trailing newline)."""

    def row(values: FloatArray) -> str:
        return "[" + ", ".join(f"{v:.{DIGITS}f}" for v in values) + "]"

    lines = ["[transient]", f"bin_s = {budget.bin_s:g}"]
    for cls, prefix in enumerate(CLASS_NAMES):
        lines.append(f"{prefix}_position_m = {row(budget.position_m[cls])}")
        lines.append(f"{prefix}_heading_rad = {row(budget.heading_rad[cls])}")
    for cls, prefix in enumerate(CLASS_NAMES):
        for axis, suffix in enumerate(_AXES):
            lines.append(f"{prefix}_{suffix} = {row(budget.envelopes[cls, :, axis])}")
    lines.append(f"estimation_position_m = {budget.estimation_position_m:.{DIGITS}f}")
    lines.append(f"estimation_heading_rad = {budget.estimation_heading_rad:.{DIGITS}f}")
    lines.append(f"source = {_toml_string(budget.source)}")
    return "\n".join(lines)


def _toml_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'
