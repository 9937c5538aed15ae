"""The stop check: a recorded stop braked the vessel to rest clear of obstacles and walls.

Every stop (an abort, an operator's stop, the time limit) brakes the vessel to rest under
the low level before the thrust is cut (the runtime's ``BRAKING``, ended by ``at_rest``).
Over that span, every recorded estimate's hull must keep more than the estimation bound
(``[transient] estimation_position_m``: the estimate is at most that far from the true
centre) from every obstacle where the log last reported it, and from the arena's walls.
Closer is a FAIL naming the time and the clearance. A log whose stop was not braked (one
written before safe stops, or a cut: a lost pose, a second stop request, a thruster fault)
is not judged here (SKIP, saying so).
"""

from __future__ import annotations

import math

import numpy as np

from hil.replay.context import ReplayContext
from hil.replay.regression import Check, Finding, Status, time_s
from hil.runtime.assembly import obstacles_from_layout
from hil.runtime.events import EventCode
from hil.runtime.settings import NS_PER_S
from hil.scenarios import Scenario

STOPS = frozenset({EventCode.STOPPED.value, EventCode.ABORTED.value, EventCode.TIMEOUT.value})
"""Events that start braking."""


def check_stop(ctx: ReplayContext) -> Check:
    """Judge the braking after the run's first stop (see module docstring)."""
    run, scenario = ctx.run, ctx.scenario
    stop = next((e for e in run.events if e.code in STOPS), None)
    if stop is None:
        return Check("stop", Status.SKIP, "the run did not stop (docked, or the log ends first)")
    rest = next(
        (e for e in run.events if e.code == EventCode.AT_REST.value and e.t_ns >= stop.t_ns), None
    )
    if rest is None:
        return Check(
            "stop",
            Status.SKIP,
            f"no braking recorded after the {stop.code} at {time_s(stop.t_ns)}: thrust was cut "
            "there (a log from before safe stops, or a cut: a lost pose, a second stop "
            "request, a thruster fault)",
        )
    t = run.estimate.t_ns
    rows = np.flatnonzero((t >= stop.t_ns) & (t <= rest.t_ns))
    bound = scenario.transient.estimation_position_m
    least_obstacle, least_wall = math.inf, math.inf
    findings: list[Finding] = []
    placed: dict[int, Scenario] = {}
    for row in rows:
        x, y, psi = (float(v) for v in run.estimate.values[row, :3])
        layout = run.layout_at(int(t[row]))
        where = scenario
        if layout is not None:
            key = id(layout)
            if key not in placed:
                placed[key] = scenario.with_obstacles(
                    obstacles_from_layout(scenario, layout.as_obstacle_layout())
                )
            where = placed[key]
        obstacle_m = where.hull_clearance_m(x, y, psi)
        wall_m = where.wall_clearance_m(x, y, psi)
        least_obstacle = min(least_obstacle, obstacle_m)
        least_wall = min(least_wall, wall_m)
        if (obstacle_m <= bound or wall_m <= bound) and len(findings) < 5:
            findings.append(
                Finding(
                    f"braking: hull {obstacle_m:.4f} m from an obstacle and {wall_m:.4f} m "
                    f"inside the walls at {time_s(int(t[row]))} (estimation bound {bound:.4f} m)",
                    int(t[row]),
                    {"obstacle_clearance_m": obstacle_m, "wall_clearance_m": wall_m},
                )
            )
    braked_s = (rest.t_ns - stop.t_ns) / NS_PER_S
    metrics = {
        "braked_s": braked_s,
        "samples": len(rows),
        "least_obstacle_clearance_m": least_obstacle,
        "least_wall_clearance_m": least_wall,
        "estimation_bound_m": bound,
    }
    summary = (
        f"braked to rest in {braked_s:.2f} s after the {stop.code} at {time_s(stop.t_ns)}; "
        f"hull at least {least_obstacle:.3f} m from the obstacles (as last reported) and "
        f"{least_wall:.3f} m inside the walls over {len(rows)} estimates"
    )
    if findings:
        return Check("stop", Status.FAIL, summary, tuple(findings), metrics)
    return Check("stop", Status.PASS, summary, (), metrics)
