"""The tracking margin the shipped low level achieves, re-derived from the code it runs.

A scenario's ``[margin]`` is the bound on |nu - nu_ref| per axis that the symbolic
abstraction absorbs. It is measured here, on the compiled closed loop of
:mod:`hil.sim.closed_loop` (the runtime's low-level tick on the simulated plant, sensors
and EKF in the loop): references change every command period as a random walk on the
scenario's input grid, at most one grid step per axis and command, and the margin is the
largest error once each period is ``settle_after_s`` old, rounded up to
``MARGIN_DIGITS`` decimals. ``python -m bench lowlevel`` prints it as a TOML table, and
a test checks that the packaged scenarios ship exactly what this derives, so a change of
gains, thrusters or vessel cannot leave a stale margin behind.

The first ``settle_after_s`` of each period (the transient after a reference step) is not
covered: the paper's assumption (1), and the open part of issue 11. The time-resolved
budget that covers the whole period is :mod:`hil.sim.transient` (``[transient]``); this
module stays until nothing reads ``[margin]`` any more.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from hil.scenarios import Scenario
from hil.sim.closed_loop import ClosedLoopResult, LowLevelConfig, simulate_closed_loop
from hil.sim.transient import input_grid

__all__ = [
    "MARGIN_DIGITS",
    "SEED0",
    "MarginRecipe",
    "SettledError",
    "derive_margin",
    "input_grid",
    "margin_from",
    "random_walk_refs",
    "settled_error",
    "settled_mask",
    "walk_runs",
]

FloatArray = NDArray[np.float64]

MARGIN_DIGITS = 4
"""Decimals of a scenario's ``[margin]`` entries (m/s, m/s, rad/s)."""

SEED0 = 1000
"""Seed of the first random walk; seed k is SEED0 + k."""


@dataclass(frozen=True, slots=True)
class MarginRecipe:
    """How the margin is measured.

    Attributes:
        seeds: Number of random walks (one closed-loop run each).
        seconds: Length of each run (s).
        settle_after_s: Errors count from this far into each command period (s).
    """

    seeds: int = 3
    seconds: float = 180.0
    settle_after_s: float = 1.0

    def describe(self) -> str:
        """Return the one-line source text a scenario stores with its margin."""
        return (
            f"hil.sim.margin (python -m bench lowlevel): max |nu - nu_ref| after settling "
            f"({self.settle_after_s:g} s into each period), {self.seeds} seeds x "
            f"{self.seconds:g} s, the runtime's low level on the simulated plant"
        )


@dataclass(frozen=True, slots=True)
class SettledError:
    """The low level's error after settling, per axis (m/s, m/s, rad/s).

    Attributes:
        worst: Largest |nu - nu_ref|, shape (3,).
        p99: 99th percentile, shape (3,).
        samples: Number of physics steps it was taken over.
    """

    worst: FloatArray
    p99: FloatArray
    samples: int

    @property
    def margin(self) -> FloatArray:
        """Return the ``[margin]`` entries: `worst` rounded up, shape (3,)."""
        return margin_from(self.worst)


def margin_from(worst: FloatArray) -> FloatArray:
    """Return `worst` (3,) rounded up to ``MARGIN_DIGITS`` decimals."""
    scale = 10.0**MARGIN_DIGITS
    out: FloatArray = np.ceil(np.asarray(worst, dtype=np.float64) * scale - 1e-9) / scale
    return out


def random_walk_refs(
    n: int, seed: int, grid: tuple[FloatArray, FloatArray, FloatArray]
) -> FloatArray:
    """Return (n, 3) references: a random walk on the grid, one step per axis at most.

    The walk starts at the grid point nearest zero velocity.
    """
    lo, hi, step = grid
    rng = np.random.default_rng(seed)
    top = np.round((hi - lo) / step).astype(int)
    idx = np.clip(np.round(-lo / step).astype(int), 0, top)
    out = np.empty((n, 3))
    for k in range(n):
        idx = np.clip(idx + rng.integers(-1, 2, size=3), 0, top)
        out[k] = lo + idx * step
    return out


def settled_mask(
    res: ClosedLoopResult, period_s: float, settle_after_s: float
) -> NDArray[np.bool_]:
    """Return which rows of `res` lie at least `settle_after_s` into their period, (N,)."""
    phase = np.mod(res.t_s + 1e-9, period_s)
    out: NDArray[np.bool_] = phase >= settle_after_s
    return out


def walk_runs(
    scenario: Scenario, recipe: MarginRecipe, config: LowLevelConfig | None = None
) -> list[ClosedLoopResult]:
    """Run the closed loop on ``recipe.seeds`` random walks of the scenario's inputs."""
    cfg = LowLevelConfig(command_period_s=scenario.tau_s) if config is None else config
    n_ref = max(1, round(recipe.seconds / cfg.command_period_s))
    grid = input_grid(scenario)
    return [
        simulate_closed_loop(random_walk_refs(n_ref, SEED0 + s, grid), replace(cfg, seed=s))
        for s in range(recipe.seeds)
    ]


def settled_error(
    runs: list[ClosedLoopResult], period_s: float, settle_after_s: float
) -> SettledError:
    """Return the error after settling pooled over `runs` (true velocity against reference)."""
    settled = np.vstack(
        [np.abs(r.nu - r.nu_ref)[settled_mask(r, period_s, settle_after_s)] for r in runs]
    )
    return SettledError(
        worst=settled.max(axis=0),
        p99=np.percentile(settled, 99.0, axis=0),
        samples=int(settled.shape[0]),
    )


def derive_margin(scenario: Scenario, recipe: MarginRecipe | None = None) -> SettledError:
    """Measure the settled error the shipped low level achieves on `scenario`'s inputs."""
    rec = MarginRecipe() if recipe is None else recipe
    return settled_error(walk_runs(scenario, rec), scenario.tau_s, rec.settle_after_s)
