"""What the transient derivation flies: its recipe, the runs it makes, their period classes.

A :class:`TransientRecipe` says how much to fly (Euler tours, walks, sweeps, the
systematic family of ramps, starts) and with which seed; :func:`recipe_runs` turns it
into :class:`Run` s of one reference per period on the scenario's input grid
(:mod:`hil.sim.reference_paths`), each period a random whole number of physics steps
in [tau, tau + LATE_S]; :func:`classify` gives each period its budget class.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from hil.core.arrays import FloatArray, IntArray
from hil.core.transient import LATE_S, START_PERIODS, BudgetClass
from hil.scenarios import Scenario
from hil.sim.errors import ClosedLoopConfigError
from hil.sim.reference_paths import InputGrid, euler_tour, ramp_family, sweeps

__all__ = [
    "DIGITS",
    "Run",
    "TransientRecipe",
    "classify",
    "hold_streaks",
    "period_steps",
    "recipe_runs",
]

DIGITS = 4
"""Decimals of the ``[transient]`` entries (m/s, m/s, rad/s, m, rad)."""


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
    g = InputGrid(scenario)
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
        add("sweeps", np.array([g.value(i) for i in sweeps(g)]), rest, zeros, 0.0)
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
