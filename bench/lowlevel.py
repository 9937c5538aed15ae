"""Low-level loop benchmark: velocity-tracking error and speed (`python -m bench lowlevel`).

What runs is the code the vessel runs: the compiled closed loop of
:mod:`hil.sim.closed_loop` calls the low-level tick of :mod:`hil.controllers.low_level`
(the runtime's ``LowLevel``) and the plant step of :mod:`hil.sim.plant` (the simulated
world's physics); tests/runtime/test_low_level_pin.py pins it tick for tick to the
runtime driving the simulated world.

Tracking: references change every 2 s as a random walk on the paper's input grid
(surge -0.1..0.2 step 0.05 m/s, sway -0.1..0.1 step 0.05 m/s, yaw rate -0.2..0.2 step
0.1 rad/s; each axis moves at most one grid step per command), simulated with sensor
noise and the EKF in the loop. The error is nu - nu_ref against the command as issued.
Printed beside the paper's tank figures, with the least error the thrust limits allow
for the same steps (an ideal jerk- and acceleration-limited response, see
`ideal_step_error`).

Transient budget: the scenario's ``[transient]`` (:mod:`hil.sim.transient`): per period
class (hold, change, start) and 0.25-s bin, how far the true position and heading stray
from the exact arc of the command started at the true pose, up to each bin's end, over
periods of tau to tau + 0.1 s (a command held late), measured on references that move at
most one grid step per axis and period (Euler tours of every (p, u) pair, walks, ramps,
starts from rest and already moving, and the systematic family: every one-step ramp of 1-4
steps into every input with 4 holds after it), x1.25 + 0.002 m / 0.002 rad and rounded up;
beside it the velocity error per bin and axis and the EKF's error, with the largest
deviation per class against the budget (the margin it leaves), the family's own worst
deviation with the factor the budget keeps over it (>= 1 in every class and bin), and
the hold periods by how many holds in a row they are (a hold settles within two
periods of a change, which is why the family holds 4).

Speed: a 3-minute run (100 Hz physics, sensors + EKF + PID + allocation + vessel) in
the compiled loop, against the same loop run by the Python interpreter
(NUMBA_DISABLE_JIT=1 in a subprocess) over a short span, extrapolated. Both in CPU
time of the process (one thread), so a busy machine inflates them less than wall time.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import subprocess
import sys
import time
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from hil.controllers.allocation_kernels import extended_matrix, force_limits
from hil.controllers.low_level import AllocatorKind
from hil.core.pose_feeds import DEFAULT_POSE_FEED, POSE_FEEDS, pose_feed
from hil.core.transient import LATE_S, BudgetClass
from hil.model.coefficients import VesselParams
from hil.model.dynamics import hydro_force
from hil.model.environment import EnvironmentalLoad
from hil.model.thrusters import ThrusterParams
from hil.scenarios import load_scenario
from hil.sim.closed_loop import (
    ClosedLoopResult,
    LowLevelConfig,
    simulate_closed_loop,
)
from hil.sim.reference_paths import input_grid
from hil.sim.sensors import pose_sensor_for
from hil.sim.transient import CLASS_NAMES, TransientDerivation, derive_transient, toml_table
from hil.sim.transient_runs import DIGITS, TransientRecipe

F = NDArray[np.float64]

GRID = input_grid(load_scenario("paper"))  # (lo, hi, step) of the paper's input grid
# Paper, Sec. V-C ("MSE" as printed): surge m/s, sway m/s, yaw deg/s.
PAPER = np.array([0.00768, 0.00431, 0.62108])
AXES = ("surge m/s", "sway m/s", "yaw deg/s")
SEED0 = 1000
"""Seed of the first random walk of the tracking figures; seed k is SEED0 + k."""


def random_walk_refs(n: int, seed: int, grid: tuple[F, F, F]) -> F:
    """Return (n, 3) references: a random walk on the grid, one step per axis at most.

    The walk starts at the grid point nearest zero velocity; `grid` is (lo, hi, step),
    each shape (3,) in (m/s, m/s, rad/s).
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




def axis_limits(vessel: VesselParams, thrusters: ThrusterParams, *, with_slew: bool) -> tuple[F, F]:
    """Return per-axis bounds on |nu_dot_i| and |nu_ddot_i| from the thrust limits.

    A_i = max over the thrust envelope of (M^-1 tau)_i (the envelope is the tunnel
    segment plus two discs, so the maximum is a sum per thruster); J_i bounds its
    rate: the tunnel's force changes at most K_t * rate, an azimuth's force vector at
    most K (rate + |u|max * slew) with slew, or K rate without (pods not yet
    turning under thrust). Drag and Coriolis are left out (see `hydro_margins`).
    """
    tp = thrusters.as_array()
    be = extended_matrix(tp)
    fmax = force_limits(tp)
    k = np.asarray(thrusters.gains_n)
    rate = thrusters.command_rate_per_s
    slew = thrusters.azimuth_rate_radps if with_slew else 0.0
    m_inv = np.linalg.inv(vessel.mass_matrix())
    a_max = np.empty(3)
    j_max = np.empty(3)
    for i in range(3):
        w = m_inv[i] @ be
        port = math.hypot(w[1], w[2])
        stbd = math.hypot(w[3], w[4])
        a_max[i] = abs(w[0]) * fmax[0] + port * fmax[1] + stbd * fmax[2]
        j_max[i] = abs(w[0]) * k[0] * rate + (port * k[1] + stbd * k[2]) * (rate + slew)
    return a_max, j_max


def hydro_margins(vessel: VesselParams) -> tuple[F, F]:
    """Bound what drag and Coriolis can add to |nu_dot_i|, and the rate they vary.

    Over the operating range widened past the grid (|u| up to 0.15 / 0.25, |v| 0.15,
    |r| 0.3), returns h_i = max |(M^-1 (C(nu) nu + D(nu) nu))_i| (3,) and the bound
    G (3, 3) of |d/dnu| of the same (central differences), so that the hydrodynamic
    part of nu_ddot_i is at most (G @ a_max)_i. Counting these as helping the
    controller (whatever their sign) keeps the bound below any real response.
    """
    m_inv = np.linalg.inv(vessel.mass_matrix())
    coef = vessel.kernel_arrays()[1]
    h = np.zeros(3)
    g = np.zeros((3, 3))
    grid = itertools.product(
        np.linspace(-0.15, 0.25, 17), np.linspace(-0.15, 0.15, 13), np.linspace(-0.3, 0.3, 25)
    )
    for u, v, r in grid:
        nu = np.array([u, v, r])
        h = np.maximum(h, np.abs(m_inv @ hydro_force(coef, nu)))
        for j in range(3):
            e = np.zeros(3)
            e[j] = 1e-6
            col = m_inv @ (hydro_force(coef, nu + e) - hydro_force(coef, nu - e)) / 2e-6
            g[:, j] = np.maximum(g[:, j], np.abs(col))
    return h, g


def ideal_step_error(delta: float, a_max: float, j_max: float) -> float:
    """Return the integral of e^2 (units^2 s) of the ideal response to a step `delta`.

    The response starts from steady state (zero acceleration: the previous reference
    held) and follows the time-optimal rest-to-rest profile with
    |acceleration| <= a_max and |jerk| <= j_max (bang-bang jerk), the fastest any
    controller can close the step; integrated exactly piecewise (fine grid).
    """
    d = abs(delta)
    if d == 0.0:
        return 0.0
    if d <= a_max * a_max / j_max:
        t_j, t_h = math.sqrt(d / j_max), 0.0
    else:
        t_j, t_h = a_max / j_max, (d - a_max * a_max / j_max) / a_max
    dt = 1e-5
    t = np.arange(0.0, 2 * t_j + t_h, dt)
    a_peak = j_max * t_j
    acc = np.where(
        t < t_j, j_max * t, np.where(t < t_j + t_h, a_peak, a_peak - j_max * (t - t_j - t_h))
    )
    v = np.cumsum(np.maximum(acc, 0.0)) * dt
    return float(np.sum((d - v) ** 2) * dt)


def ideal_rms(refs: F, period_s: float, a_max: F, j_max: F) -> F:
    """Return the per-axis RMS error of the ideal response to a reference sequence."""
    steps = np.diff(np.vstack([np.zeros((1, 3)), refs]), axis=0)
    total = np.zeros(3)
    cache: dict[tuple[int, float], float] = {}
    for row in steps:
        for i in range(3):
            key = (i, round(abs(row[i]), 9))
            if key not in cache:
                cache[key] = ideal_step_error(abs(row[i]), a_max[i], j_max[i])
            total[i] += cache[key]
    out: F = np.sqrt(total / (refs.shape[0] * period_s))
    return out


def tracking_errors(res: ClosedLoopResult) -> F:
    """Return the error nu - nu_ref, shape (N, 3)."""
    out: F = res.nu - res.nu_ref
    return out




def to_display(x: F) -> F:
    """Convert a per-axis (m/s, m/s, rad/s) row to (m/s, m/s, deg/s)."""
    out = np.array(x, dtype=np.float64)
    out[..., 2] = np.degrees(out[..., 2])
    return out




def fmt_row(label: str, values: F, digits: int = 5) -> str:
    cells = "".join(f"{v:>14.{digits}f}" for v in values)
    return f"  {label:<44}{cells}"


def run_variant(cfg: LowLevelConfig, refs: list[F]) -> tuple[F, F, list[ClosedLoopResult]]:
    """Run every seed; return (rms (3,), mse (3,), the results), errors pooled."""
    runs = [simulate_closed_loop(r, replace(cfg, seed=seed)) for seed, r in enumerate(refs)]
    e = np.vstack([tracking_errors(res) for res in runs])
    mse: F = np.mean(e**2, axis=0)
    return np.sqrt(mse), mse, runs


def interpreted_seconds(span_s: float) -> float:
    """Time `span_s` simulated seconds of the same loop under NUMBA_DISABLE_JIT=1."""
    code = (
        "import time, numpy as np\n"
        "from bench.lowlevel import GRID, random_walk_refs\n"
        "from hil.sim.closed_loop import simulate_closed_loop, LowLevelConfig\n"
        f"refs = random_walk_refs({max(1, round(span_s / 2.0))}, 0, GRID)\n"
        "t = time.process_time(); simulate_closed_loop(refs, LowLevelConfig())\n"
        "print(time.process_time() - t)\n"
    )
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    return float(out.stdout.strip().splitlines()[-1])


def transient_report(cfg: LowLevelConfig, feed: str) -> TransientDerivation:
    """Derive and print the paper scenario's transient budget with `cfg`'s sensors (`feed`)."""
    recipe_t = TransientRecipe()
    derivation = derive_transient(load_scenario("paper"), recipe_t, cfg)
    if feed != DEFAULT_POSE_FEED:
        derivation = replace(derivation, budget=replace(
            derivation.budget, source=f"{derivation.budget.source}; pose feed {feed}"))
    budget = derivation.budget
    measured = derivation.measured
    periods = ", ".join(
        f"{n} {name}" for n, name in zip(measured.periods, CLASS_NAMES, strict=True)
    )
    print(
        "\ntransient: deviation from the exact arc of the command started at the true pose, "
        f"per period class,\n  up to the end of each bin (pose feed {feed}; periods of tau to "
        f"tau + {LATE_S:g} s)"
    )
    print(
        f"  {periods} periods, {measured.simulated_s:.0f} s simulated, derived in "
        f"{derivation.seconds:.1f} s (wall, one core)"
    )
    edges = [j * budget.bin_s for j in range(budget.n_bins + 1)]
    bin_header = "".join(f"{f'{a:g}-{b:g}':>10}" for a, b in itertools.pairwise(edges))
    print(f"  {'measured (s)':<22}{bin_header}")
    for cls, cls_name in enumerate(CLASS_NAMES):
        for label, row in (
            ("position m", measured.position_m[cls]),
            ("heading rad", measured.heading_rad[cls]),
        ):
            print(f"  {cls_name + ' ' + label:<22}" + "".join(f"{v:>10.4f}" for v in row))
    for cls, cls_name in enumerate(CLASS_NAMES):
        for axis, axis_name in enumerate(("surge m/s", "sway m/s", "yaw rate rad/s")):
            cells = "".join(f"{v:>10.4f}" for v in measured.envelopes[cls, :, axis])
            print(f"  {cls_name + ' ' + axis_name:<22}{cells}")
    print(
        f"  EKF error after {recipe_t.estimation_after_s:g} s: position "
        f"{measured.estimation[0]:.4f} m, heading {measured.estimation[1]:.4f} rad"
    )
    ratios = derivation.ratios
    print("  largest deviation per class against the budget (max over bins of measured/budget):")
    for cls, cls_name in enumerate(CLASS_NAMES):
        print(
            f"    {cls_name:<7} position {ratios.position_m[cls]:.4f} m of "
            f"{budget.position_m[cls, -1]:.4f} (ratio {ratios.position[cls]:.3f}), heading "
            f"{ratios.heading_rad[cls]:.4f} rad of {budget.heading_rad[cls, -1]:.4f} "
            f"(ratio {ratios.heading[cls]:.3f})"
        )
    fam = measured.family_periods
    print(
        f"  the systematic family ({fam[0]} hold, {fam[1]} change periods: every one-step "
        f"ramp of 1-{recipe_t.ramp_steps} steps into every input, {recipe_t.ramp_holds} "
        "holds after),\n  its worst deviation and the factor the budget keeps over it "
        "(budget / measured, >= 1 required):"
    )
    print(f"  {'family (s)':<22}{bin_header}")
    f_position, f_heading = derivation.family_factors()
    for cls in (BudgetClass.HOLD, BudgetClass.CHANGE):
        cls_name = CLASS_NAMES[cls]
        for label, row in (
            ("position m", measured.family_position_m[cls]),
            ("position factor", f_position[cls]),
            ("heading rad", measured.family_heading_rad[cls]),
            ("heading factor", f_heading[cls]),
        ):
            print(f"  {cls_name + ' ' + label:<22}" + "".join(f"{v:>10.4f}" for v in row))
    print("  hold periods by holds in a row since the last change (position m; settled by 2):")
    streaks = measured.hold_streak_position_m
    for h in range(streaks.shape[0]):
        label = f"hold {h + 1}{'+' if h == streaks.shape[0] - 1 else ''}"
        print(f"  {label:<22}" + "".join(f"{v:>10.4f}" for v in streaks[h]))
    print(
        f"\nscenario transient budget this measures (deviations x{recipe_t.safety_factor:g} + "
        f"{recipe_t.position_margin_m:g} m / {recipe_t.heading_margin_rad:g} rad, the rest "
        f"x{recipe_t.safety_factor:g}, rounded up to {DIGITS} decimals):"
    )
    print("\n".join(f"  {line}" for line in toml_table(budget).splitlines()))
    return derivation


def main(argv: list[str] | None = None) -> int:
    """Print tracking error, bounds and loop speed; return 0."""
    parser = argparse.ArgumentParser(prog="python -m bench lowlevel", description=__doc__)
    parser.add_argument("--seconds", type=float, default=180.0, help="run length (s)")
    parser.add_argument("--seeds", type=int, default=3, help="random-walk seeds")
    parser.add_argument("--repeats", type=int, default=5, help="timing repeats (best of)")
    parser.add_argument("--baseline-seconds", type=float, default=4.0, help="interpreted span (s)")
    parser.add_argument("--json", action="store_true", help="also print a JSON summary")
    parser.add_argument("--pose-feed", default=DEFAULT_POSE_FEED, choices=sorted(POSE_FEEDS),
                        help="the pose feed the sensors simulate (hil.core.pose_feeds)")
    parser.add_argument("--transient-only", action="store_true",
                        help="derive the transient budget only (no tracking, no speed)")
    args = parser.parse_args(argv)

    cfg = LowLevelConfig(pose_sensor=pose_sensor_for(pose_feed(args.pose_feed)))
    if args.transient_only:
        transient_report(cfg, args.pose_feed)
        return 0
    period = cfg.command_period_s
    n_ref = max(1, round(args.seconds / period))
    refs = [random_walk_refs(n_ref, SEED0 + s, GRID) for s in range(args.seeds)]

    t0 = time.perf_counter()
    simulate_closed_loop(refs[0][:2], cfg)  # compile (or load the cache)
    compile_s = time.perf_counter() - t0

    print(
        "low-level loop: the code the vessel runs (hil.controllers.low_level.low_level_tick, "
        "the runtime's LowLevel) on the simulated plant (hil.sim.plant.plant_step)"
    )
    print(
        f"  {args.seeds} seeds x {n_ref * period:.0f} s, references every "
        f"{period:.0f} s (random walk on the paper's grid), sensors + EKF on, "
        f"PID/allocation {1.0 / cfg.control_period_s:.0f} Hz, physics {1.0 / cfg.dt_s:.0f} Hz"
    )
    print(f"  first call (compile or cache load): {compile_s:.2f} s")

    # ---- tracking ----
    variants = {
        "EKF + min-magnitude/azimuth alloc (default)": cfg,
        "true velocity (no sensors/EKF)": replace(cfg, observer=None),
        "EKF + plain pseudo-inverse alloc": replace(cfg, allocator=AllocatorKind.PSEUDO_INVERSE),
        "EKF + PID/allocation every physics step": replace(cfg, control_period_s=cfg.dt_s),
        "EKF + slowly varying load (GM 0.1 N, 30 s)": replace(
            cfg,
            environment=EnvironmentalLoad(
                gm_std_n=(0.1, 0.1, 0.03), gm_time_constant_s=30.0, seed=11
            ),
        ),
    }
    results = {name: run_variant(v, refs) for name, v in variants.items()}
    rms, mse, _ = results["EKF + min-magnitude/azimuth alloc (default)"]

    a_thrust, j_thrust = axis_limits(cfg.vessel, cfg.thrusters, with_slew=True)
    h_max, h_jac = hydro_margins(cfg.vessel)
    a_strict = a_thrust + h_max
    j_strict = j_thrust + h_jac @ a_strict
    a_idle, j_idle = axis_limits(cfg.vessel, cfg.thrusters, with_slew=False)
    bound_strict = np.sqrt(
        np.mean([ideal_rms(r, period, a_strict, j_strict) ** 2 for r in refs], axis=0)
    )
    bound_idle = np.sqrt(np.mean([ideal_rms(r, period, a_idle, j_idle) ** 2 for r in refs], axis=0))

    header = "".join(f"{a:>14}" for a in AXES)
    print("\nvelocity tracking error nu - nu_ref (against the command as issued)")
    print(f"  {'':<44}{header}")
    print(fmt_row("paper, towing tank (printed as 'MSE')", PAPER))
    for name, (r_rms, _, _) in results.items():
        print(fmt_row(f"RMS  {name}", to_display(r_rms)))
    print(
        fmt_row(
            "MSE  default (units^2; yaw in (deg/s)^2)",
            np.array([mse[0], mse[1], np.degrees(np.degrees(mse[2]))]),
            7,
        )
    )
    print(fmt_row("least RMS the limits allow (strict bound)", to_display(bound_strict)))
    print(fmt_row("ideal RMS from idle thrusters (yardstick)", to_display(bound_idle)))
    ratio = to_display(rms) / PAPER
    print(fmt_row("default RMS / paper", ratio, 2))
    print(
        fmt_row(
            "paper / strict bound (< 1: paper unreachable)", PAPER / to_display(bound_strict), 2
        )
    )
    print(fmt_row("default RMS / strict bound", rms / bound_strict, 2))
    print("  strict bound: per axis, the time-optimal response to each step with |nu_dot| and its")
    print("  rate bounded by the thrust envelope, the command rate (2 /s) and the pod slew rate,")
    print("  plus all that drag and Coriolis could add over the operating range, as if they always")
    print("  helped. Idle: thrust only, no slew (thrusters start from zero), no hydrodynamics;")
    print("  a yardstick for a controller starting from idle thrusters, not a bound.")
    print(
        f"  limits used: accel {np.round(to_display(a_strict), 3)} per s, jerk strict "
        f"{np.round(to_display(j_strict), 3)}, idle {np.round(to_display(j_idle), 3)} per s^2"
    )

    # ---- transient budget (the scenario's [transient]) ----
    derivation = transient_report(cfg, args.pose_feed)
    measured, budget, ratios = derivation.measured, derivation.budget, derivation.ratios
    f_position, f_heading = derivation.family_factors()
    streaks = measured.hold_streak_position_m

    # ---- speed ----
    long_refs = random_walk_refs(round(180.0 / period), 7, GRID)
    best = math.inf
    best_wall = math.inf
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        c0 = time.process_time()
        simulate_closed_loop(long_refs, cfg)
        best = min(best, time.process_time() - c0)
        best_wall = min(best_wall, time.perf_counter() - t0)
    sim_s = long_refs.shape[0] * period
    base_span = args.baseline_seconds
    base_s = interpreted_seconds(base_span) * (sim_s / (max(1, round(base_span / 2.0)) * 2.0))
    print(
        f"\nspeed: {sim_s:.0f} s simulated "
        "(100 Hz physics, sensors + EKF + PID + allocation + vessel)"
    )
    print(
        f"  compiled loop, CPU time (best of {args.repeats}): {best:8.4f} s   "
        f"{sim_s / best:9.0f}x real time   target <= 0.18 s: "
        f"{'met' if best <= 0.18 else 'MISSED'}"
    )
    print(
        f"  compiled loop, wall time (best of {args.repeats}): {best_wall:8.4f} s   "
        f"{sim_s / best_wall:9.0f}x real time (includes waiting for a shared core)"
    )
    print(
        f"  interpreted (same code, NUMBA_DISABLE_JIT, {base_span:.0f} s extrapolated): "
        f"{base_s:8.2f} s   {sim_s / base_s:9.1f}x real time"
    )
    print(f"  speed-up over the interpreted loop: {base_s / best:.0f}x")

    if args.json:
        print(
            json.dumps(
                {
                    "rms": to_display(rms).tolist(),
                    "mse_si": mse.tolist(),
                    "paper": PAPER.tolist(),
                    "bound_strict_rms": to_display(bound_strict).tolist(),
                    "bound_idle_rms": to_display(bound_idle).tolist(),
                    "transient": {
                        "position_m": measured.position_m.tolist(),
                        "heading_rad": measured.heading_rad.tolist(),
                        "envelopes_si": measured.envelopes.tolist(),
                        "budget_position_m": budget.position_m.tolist(),
                        "budget_heading_rad": budget.heading_rad.tolist(),
                        "budget_envelopes_si": budget.envelopes.tolist(),
                        "estimation": measured.estimation.tolist(),
                        "periods": measured.periods.tolist(),
                        "worst_ratio": ratios.worst,
                        "family_position_m": measured.family_position_m.tolist(),
                        "family_heading_rad": measured.family_heading_rad.tolist(),
                        "family_factor_position": f_position.tolist(),
                        "family_factor_heading": f_heading.tolist(),
                        "hold_streak_position_m": streaks.tolist(),
                        "seconds": derivation.seconds,
                    },
                    "loop_s": best,
                    "realtime_factor": sim_s / best,
                    "interpreted_s": base_s,
                }
            )
        )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
