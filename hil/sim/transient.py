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

import time
from dataclasses import dataclass, replace

import numpy as np

from hil.controllers.symbolic.abstraction import displacement
from hil.core.arrays import FloatArray, IntArray
from hil.core.geometry import wrap_angles
from hil.core.transient import (
    N_CLASSES,
    TransientBudget,
    horizon_bins,
)
from hil.scenarios import Scenario
from hil.sim.closed_loop import ClosedLoopResult, LowLevelConfig, simulate_closed_loop
from hil.sim.transient_runs import (
    DIGITS,
    Run,
    TransientRecipe,
    classify,
    hold_streaks,
    recipe_runs,
)

__all__ = [
    "CLASS_NAMES",
    "BoundRatios",
    "Measured",
    "TransientDerivation",
    "check_bound",
    "derive_transient",
    "fly",
    "measure",
    "round_up",
    "toml_table",
]

CLASS_NAMES = ("hold", "change", "start")
"""The classes' names, by :class:`~hil.core.transient.BudgetClass` (the TOML key prefixes)."""

_AXES = ("surge_mps", "sway_mps", "yaw_rate_radps")

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


def round_up(values: FloatArray, digits: int = DIGITS) -> FloatArray:
    """Return `values` rounded up to `digits` decimals (same shape)."""
    scale = 10.0**digits
    out: FloatArray = np.ceil(np.asarray(values, dtype=np.float64) * scale - 1e-9) / scale
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
