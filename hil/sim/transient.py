"""The transient budget the shipped low level achieves, derived from the code it runs.

A scenario's ``[transient]`` (:class:`~hil.core.transient.TransientBudget`) bounds the
true velocity error ``|nu - nu_ref|`` per axis over each command period, in time bins,
for two classes of period: *hold* (the reference equals the previous one) and *change*
(it moved by at most one input-grid step per axis, or the period is the first of a run
that started moving). It is measured here on the compiled closed loop of
:mod:`hil.sim.closed_loop` (the runtime's low-level tick on the simulated plant, sensors
and EKF in the loop), on references that obey the game's rule: each period the
reference stays or moves to a neighbour on the scenario's input grid.

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
- *moving starts*, for every pair (p*, u in N(p*)): the true velocity drawn uniformly
  within half a grid step of p* (clipped to the input box), thrusters idle, a random
  heading, the EKF from the true state as configured, the first reference u (class
  change), then a walk; and once more from the corner of that half-step box farthest
  from u (the largest first step the rule allows), u then held (the tail of that step
  is the largest a hold sees: the thrusters start idle).

Every period is classified, and per class, bin and axis the largest ``|nu - nu_ref|``
over all physics samples in the bin (both edges: the sample at t = tau closes a period)
is multiplied by ``safety_factor`` and rounded up to ``DIGITS`` decimals. The
estimation bounds are the largest EKF position and heading errors of every run after
its first ``estimation_after_s``, scaled and rounded alike. The same runs check the
bound: each period's true deviation from the exact arc of its
reference started at the true pose against ``position_bound_m`` / ``heading_bound_rad``
(:func:`check_bound` on fresh seeds).

``python -m bench lowlevel`` prints the table; tests/sim/test_transient_derivation.py checks that
the packaged scenarios ship it and that fresh runs stay inside the bound.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from hil.controllers.symbolic.abstraction import displacement
from hil.core.geometry import wrap_angles
from hil.core.transient import N_CLASSES, BudgetClass, TransientBudget
from hil.scenarios import Scenario
from hil.sim.closed_loop import ClosedLoopResult, LowLevelConfig, simulate_closed_loop
from hil.sim.errors import ClosedLoopConfigError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

__all__ = [
    "DIGITS",
    "BoundRatios",
    "Run",
    "TransientDerivation",
    "TransientRecipe",
    "check_bound",
    "classify",
    "derive_transient",
    "euler_tour",
    "input_grid",
    "recipe_runs",
    "round_up",
    "toml_table",
]

DIGITS = 4
"""Decimals of the ``[transient]`` entries (m/s, m/s, rad/s, m, rad)."""

_DIRECTIONS = np.array(
    [d for d in itertools.product((-1, 0, 1), repeat=3) if any(d)], dtype=np.int64
)  # (26, 3): the non-zero one-step moves
_MOVES = np.array(list(itertools.product((-1, 0, 1), repeat=3)), dtype=np.int64)  # (27, 3)


@dataclass(frozen=True, slots=True)
class TransientRecipe:
    """How the transient budget is measured (the default: ~20 s on one core, 44,000 s flown).

    Attributes:
        tours: Randomized Euler tours over every (p, u in N(p)) pair, one run each.
        walks: Long random walks from rest, one run each.
        walk_s: Length of each walk (s).
        sweeps: Whether to fly the 26 ramps (one run).
        moving: Passes over every (p*, u in N(p*)) pair starting moving, one run each.
        moving_corners: Whether to add, for every pair, a start at the corner of the
            half-step box around p* farthest from u, then u held.
        moving_share: Share of the pairs each moving pass starts from (drawn at random;
            1: every pair), for quick checks.
        moving_periods: Periods of each moving run (the first is a change).
        n_bins: Time bins per command period.
        safety_factor: Factor on every measured maximum.
        estimation_after_s: The EKF's errors count from this far into each run (s).
        seed: Seed of the references, starts and sensor noise (a derivation is a
            deterministic function of the recipe).
    """

    tours: int = 2
    walks: int = 4
    walk_s: float = 180.0
    sweeps: bool = True
    moving: int = 1
    moving_corners: bool = True
    moving_share: float = 1.0
    moving_periods: int = 2
    n_bins: int = 8
    safety_factor: float = 1.2
    estimation_after_s: float = 2.0
    seed: int = 2000

    def describe(self) -> str:
        """Return the one-line source text a scenario stores with its budget."""
        return (
            f"hil.sim.transient (python -m bench lowlevel): max |nu - nu_ref| per class, "
            f"{self.n_bins} bins x axis, x{self.safety_factor:g}, rounded up; {self.tours} "
            f"Euler tours of all (p, u in N(p)) pairs, {self.walks} walks x {self.walk_s:g} s, "
            f"{'26 ramps, ' if self.sweeps else ''}moving starts from {self.moving}"
            f"{' + 1 (farthest corner)' if self.moving_corners else ''} x "
            f"{'all' if self.moving_share >= 1.0 else f'{self.moving_share:g} of the'} pairs, "
            f"{self.moving_periods} periods each; seed {self.seed}; the runtime's low level on the "
            "simulated plant, sensors and EKF"
        )


@dataclass(frozen=True, slots=True, eq=False)
class Run:
    """One closed-loop run of the recipe: its references and where it starts.

    Attributes:
        kind: ``tour``, ``walk``, ``sweeps``, ``moving`` or ``corner``.
        refs: References, shape (N, 3) (m/s, m/s, rad/s), one per period.
        previous: The reference before the first period, shape (3,): the input nearest
            zero from rest, p* for a moving start.
        nu0: Initial true velocity, shape (3,).
        eta0: Initial pose, shape (3,) (m, m, rad).
        seed: Sensor-noise seed.
        moving: Whether the run starts moving (its first period is then a change).
    """

    kind: str
    refs: FloatArray
    previous: FloatArray
    nu0: FloatArray
    eta0: FloatArray
    seed: int
    moving: bool


@dataclass(frozen=True, slots=True)
class BoundRatios:
    """The worst true deviation from the exact arc over the bound, per class.

    Attributes:
        position: Max over periods and samples (t > 0) of |p - pbar| / rho, shape (2,).
        heading: Max of |psi - psibar| / theta, shape (2,).
        position_m: Largest |p - pbar| (m) per class, shape (2,).
        heading_rad: Largest |psi - psibar| (rad) per class, shape (2,).
        periods: Periods judged per class, shape (2,).
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
        budget: The scenario's ``[transient]``: measured maxima x safety factor, rounded.
        envelopes: The measured maxima, shape (2, n_bins, 3) [class, bin, axis].
        estimation: Measured max EKF errors (position m, heading rad), shape (2,).
        periods: Periods measured per class, shape (2,).
        samples: Physics samples per class, shape (2,).
        ratios: The bound checked on the same runs against `budget`.
        seconds: Wall time of the derivation (s).
        simulated_s: Simulated time (s).
    """

    budget: TransientBudget
    envelopes: FloatArray
    estimation: FloatArray
    periods: IntArray
    samples: IntArray
    ratios: BoundRatios
    seconds: float
    simulated_s: float = field(default=0.0)


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
        """Return N(idx), shape (k, 3), k <= 27, idx included."""
        cand = idx[None, :] + _MOVES
        ok = np.all((cand >= 0) & (cand <= self.top), axis=1)
        out: IntArray = cand[ok]
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


def recipe_runs(scenario: Scenario, recipe: TransientRecipe) -> list[Run]:
    """Return the runs of `recipe` on `scenario`'s input grid (deterministic in the seed)."""
    g = _Grid(scenario)
    rng = np.random.default_rng(recipe.seed)
    rest = g.value(g.zero)
    zeros = np.zeros(3)
    seeds = itertools.count(recipe.seed)
    runs = [
        Run("tour", euler_tour(scenario, rng), rest, zeros, zeros, next(seeds), False)
        for _ in range(recipe.tours)
    ]
    n_walk = max(1, round(recipe.walk_s / scenario.tau_s))
    for _ in range(recipe.walks):
        refs = np.array([g.value(i) for i in g.walk(g.zero, n_walk, rng)])
        runs.append(Run("walk", refs, rest, zeros, zeros, next(seeds), False))
    if recipe.sweeps:
        refs = np.array([g.value(i) for i in _sweeps(g)])
        runs.append(Run("sweeps", refs, rest, zeros, zeros, next(seeds), False))
    pairs = [(p, u) for p in g.inputs() for u in g.neighbours(p)]
    n_pairs = round(recipe.moving_share * len(pairs))

    def some_pairs() -> list[tuple[IntArray, IntArray]]:
        if n_pairs >= len(pairs):
            return pairs
        return [pairs[k] for k in sorted(rng.choice(len(pairs), n_pairs, replace=False))]

    for _ in range(recipe.moving):
        for star, first in some_pairs():
            p_star = g.value(star)
            nu0 = np.clip(p_star + rng.uniform(-0.5, 0.5, 3) * g.step, g.lo, g.hi)
            idx = [first, *g.walk(first, recipe.moving_periods - 1, rng)]
            eta0 = np.array([0.0, 0.0, rng.uniform(-math.pi, math.pi)])
            refs = np.array([g.value(i) for i in idx])
            runs.append(Run("moving", refs, p_star, nu0, eta0, next(seeds), True))
    if recipe.moving_corners:
        for star, first in some_pairs():
            p_star = g.value(star)
            away = np.sign(first - star).astype(np.float64)
            away[away == 0.0] = rng.choice((-1.0, 1.0), size=int(np.sum(away == 0.0)))
            nu0 = np.clip(p_star - 0.5 * away * g.step, g.lo, g.hi)
            refs = np.repeat(g.value(first)[None, :], recipe.moving_periods, axis=0)
            eta0 = np.array([0.0, 0.0, rng.uniform(-math.pi, math.pi)])
            runs.append(Run("corner", refs, p_star, nu0, eta0, next(seeds), True))
    return runs


def classify(run: Run) -> IntArray:
    """Return the budget class of each period of `run`, shape (N,) (0 hold, 1 change).

    A period holds when its reference equals the one before; the first period of a
    moving run is a change, and so is the first from rest unless the vessel rests at
    its previous reference (the input nearest zero is zero).
    """
    prev = np.vstack([run.previous[None, :], run.refs[:-1]])
    out = np.where(np.all(run.refs == prev, axis=1), BudgetClass.HOLD, BudgetClass.CHANGE)
    if run.moving or np.any(run.previous != run.nu0):
        out[0] = BudgetClass.CHANGE
    return out.astype(np.int64)


@dataclass(frozen=True, slots=True)
class _Periods:
    """One run cut into periods: binned errors and arc deviations at every physics sample.

    Attributes:
        classes: (N,) budget classes.
        speed: (N,) reference speeds |u_lin| (m/s).
        t: (S + 1,) times into the period (s); sample S is the next period's first.
        binned: (N, n_bins, 3) max |nu - nu_ref| per bin and axis (a period's missing
            closing sample, at the end of a run, counts as 0).
        samples: (N,) physics samples of each period (S + 1, S for a run's last).
        dev_p: (N, S + 1) |p - pbar| (m).
        dev_psi: (N, S + 1) |psi - psibar| (rad).
        estimation: (2,) max EKF position (m) and heading (rad) errors after the start.
    """

    classes: IntArray
    speed: FloatArray
    t: FloatArray
    binned: FloatArray
    samples: IntArray
    dev_p: FloatArray
    dev_psi: FloatArray
    estimation: FloatArray


def _periods(
    run: Run, res: ClosedLoopResult, t: FloatArray, bins: list[slice], after_s: float
) -> _Periods:
    n = run.refs.shape[0]
    steps = t.shape[0] - 1
    total = res.t_s.shape[0]
    idx = np.arange(n)[:, None] * steps + np.arange(steps + 1)[None, :]
    valid = idx < total
    idx = np.minimum(idx, total - 1)
    error = np.abs(res.nu[idx] - run.refs[:, None, :])
    error[~valid] = 0.0
    binned = np.stack([error[:, b].max(axis=1) for b in bins], axis=1)
    start = res.eta[np.arange(n) * steps]  # (N, 3) true pose at each period's start
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
        speed=np.hypot(run.refs[:, 0], run.refs[:, 1]),
        t=t,
        binned=binned,
        samples=valid.sum(axis=1),
        dev_p=dev_p,
        dev_psi=dev_psi,
        estimation=est,
    )


def _bin_slices(t: FloatArray, bin_s: float, n_bins: int) -> list[slice]:
    """Return, per bin j, the samples of `t` (T,) in [j bin_s, (j + 1) bin_s] (both edges)."""
    eps = 1e-9 * max(1.0, bin_s)
    out = []
    for j in range(n_bins):
        inside = np.nonzero((t >= j * bin_s - eps) & (t <= (j + 1) * bin_s + eps))[0]
        out.append(slice(int(inside[0]), int(inside[-1]) + 1))
    return out


def _bound_ratios(budget: TransientBudget, periods: list[_Periods]) -> BoundRatios:
    """Return the worst deviation from the exact arc over `budget`'s bound, per class.

    Samples at t = 0 (deviation and bound both zero) and where a bound is zero with a
    zero deviation are skipped; a deviation where the bound is zero counts as inf.
    """
    pos = np.zeros(N_CLASSES)
    head = np.zeros(N_CLASSES)
    pos_m = np.zeros(N_CLASSES)
    head_rad = np.zeros(N_CLASSES)
    counts = np.zeros(N_CLASSES, dtype=np.int64)
    for p in periods:
        later = p.t > 0.0
        for cls in range(N_CLASSES):
            rows = p.classes == cls
            if not np.any(rows):
                continue
            counts[cls] += int(rows.sum())
            rho = budget.position_bound_m(cls, p.speed[rows], p.t[later])
            theta = budget.heading_bound_rad(cls, p.t[later])[None, :]
            dp = p.dev_p[rows][:, later]
            dh = p.dev_psi[rows][:, later]
            pos[cls] = max(pos[cls], _worst_ratio(dp, rho))
            head[cls] = max(head[cls], _worst_ratio(dh, np.broadcast_to(theta, dh.shape)))
            pos_m[cls] = max(pos_m[cls], float(dp.max(initial=0.0)))
            head_rad[cls] = max(head_rad[cls], float(dh.max(initial=0.0)))
    return BoundRatios(pos, head, pos_m, head_rad, counts)


def _worst_ratio(dev: FloatArray, bound: FloatArray) -> float:
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(bound > 0.0, dev / bound, np.where(dev > 0.0, np.inf, 0.0))
    return float(ratio.max(initial=0.0))


def _measure(
    scenario: Scenario, recipe: TransientRecipe, config: LowLevelConfig | None = None
) -> tuple[list[_Periods], float]:
    """Fly every run of `recipe`; return the periods and the simulated time (s).

    Raises:
        ClosedLoopConfigError: A bin is not a whole number of physics steps.
    """
    cfg = LowLevelConfig(command_period_s=scenario.tau_s) if config is None else config
    steps = cfg.steps_per_command
    bin_s = cfg.command_period_s / recipe.n_bins
    if abs(bin_s / cfg.dt_s - round(bin_s / cfg.dt_s)) > 1e-6:
        raise ClosedLoopConfigError(
            f"a bin of {bin_s!r} s ({recipe.n_bins} per period) is not a whole number of "
            f"physics steps dt_s={cfg.dt_s!r}"
        )
    t: FloatArray = np.arange(steps + 1, dtype=np.float64) * cfg.dt_s
    bins = _bin_slices(t, bin_s, recipe.n_bins)
    runs = recipe_runs(scenario, recipe)
    periods = []
    for run in runs:
        res = simulate_closed_loop(run.refs, replace(cfg, seed=run.seed), run.eta0, run.nu0)
        periods.append(_periods(run, res, t, bins, recipe.estimation_after_s))
    simulated = sum(r.refs.shape[0] for r in runs) * cfg.command_period_s
    return periods, simulated


def derive_transient(
    scenario: Scenario,
    recipe: TransientRecipe | None = None,
    config: LowLevelConfig | None = None,
) -> TransientDerivation:
    """Measure the transient budget the shipped low level achieves on `scenario`'s inputs.

    Args:
        scenario: Its input grid and command period ``tau_s`` are used.
        recipe: How to measure (default: :class:`TransientRecipe`).
        config: The low level (default: the vessel's, at the scenario's period).

    Returns:
        The budget (measured maxima x safety factor, rounded up to ``DIGITS``), the raw
        maxima and the bound checked on the same runs.
    """
    rec = TransientRecipe() if recipe is None else recipe
    t0 = time.perf_counter()
    periods, simulated = _measure(scenario, rec, config)
    bin_s = scenario.tau_s / rec.n_bins
    env = np.zeros((N_CLASSES, rec.n_bins, 3))
    est = np.zeros(2)
    counts = np.zeros(N_CLASSES, dtype=np.int64)
    samples = np.zeros(N_CLASSES, dtype=np.int64)
    for p in periods:
        est = np.maximum(est, p.estimation)
        for cls in range(N_CLASSES):
            rows = p.classes == cls
            if not np.any(rows):
                continue
            counts[cls] += int(rows.sum())
            samples[cls] += int(p.samples[rows].sum())
            env[cls] = np.maximum(env[cls], p.binned[rows].max(axis=0))
    budget = TransientBudget(
        bin_s=bin_s,
        envelopes=round_up(env * rec.safety_factor),
        estimation_position_m=float(round_up(est[0] * rec.safety_factor)),
        estimation_heading_rad=float(round_up(est[1] * rec.safety_factor)),
        source=rec.describe(),
    )
    ratios = _bound_ratios(budget, periods)
    return TransientDerivation(
        budget=budget,
        envelopes=env,
        estimation=est,
        periods=counts,
        samples=samples,
        ratios=ratios,
        seconds=time.perf_counter() - t0,
        simulated_s=simulated,
    )


def check_bound(
    scenario: Scenario,
    budget: TransientBudget,
    recipe: TransientRecipe,
    config: LowLevelConfig | None = None,
) -> BoundRatios:
    """Fly `recipe` (fresh seeds: choose its ``seed``) and judge every period by `budget`."""
    periods, _ = _measure(scenario, recipe, config)
    return _bound_ratios(budget, periods)


def toml_table(budget: TransientBudget) -> str:
    """Return `budget` as the scenario's ``[transient]`` TOML table (no trailing newline)."""

    def row(values: FloatArray) -> str:
        return "[" + ", ".join(f"{v:.{DIGITS}f}" for v in values) + "]"

    lines = ["[transient]", f"bin_s = {budget.bin_s:g}"]
    for cls, prefix in ((BudgetClass.HOLD, "hold"), (BudgetClass.CHANGE, "change")):
        for axis, suffix in enumerate(("surge_mps", "sway_mps", "yaw_rate_radps")):
            lines.append(f"{prefix}_{suffix} = {row(budget.envelopes[cls, :, axis])}")
    lines.append(f"estimation_position_m = {budget.estimation_position_m:.{DIGITS}f}")
    lines.append(f"estimation_heading_rad = {budget.estimation_heading_rad:.{DIGITS}f}")
    lines.append(f"source = {_toml_string(budget.source)}")
    return "\n".join(lines)


def _toml_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'
