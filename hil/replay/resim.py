"""The resim check: the recorded run simulated again with the current code (closed loop).

The recorded scenario, seed and start (from the suite manifest beside the log
when there is one, else the run specification in the metadata, else the first
recorded pose) are simulated again and the trajectory, decisions and tracking
error compared with the recording: positions within ``Tolerance.resim_position_m``,
decisions exactly up to one taken the other way at a cell boundary or a cost tie within
tolerance (:func:`hil.replay.decisions.compare_rerun_decisions`), which is accepted and
reported and after which nothing is compared (the closed loop then flies another
legitimate trajectory).
"""

from __future__ import annotations

import json
import math

import numpy as np

from hil.bag.run_data import RunData, Series
from hil.core.clock import NS_PER_S
from hil.replay.context import ReplayContext
from hil.replay.controllers import ScenarioMismatchError
from hil.replay.divergence import BOUNDARY, TIE, compare_rerun_decisions
from hil.replay.regression import Check, Finding, Status, time_s
from hil.replay.stack_rerun import compared_until, divergence_note, tracking_of, until
from hil.replay.tracking_checks import tracking_findings
from hil.runs.sim_run import SimRunSpec, run_in_sim, spec_from_json
from hil.runtime.settings import LoopConfig
from hil.runtime.trace import MemoryLog

MANIFEST = "suite.json"
"""File beside a suite's logs that holds each run's full specification (start, faults)."""


def recorded_spec(run: RunData) -> tuple[SimRunSpec, str]:
    """Return the specification that reproduces `run` and where it came from.

    The suite manifest beside the log holds the exact start, faults and motions;
    without it the metadata's scenario and seed are used with the first recorded
    pose as start (noisy by the sensor's noise, so decisions may drift).

    Raises:
        ScenarioMismatchError: Without a manifest entry, the log lacks scenario or seed.
    """
    manifest = run.path.parent / MANIFEST
    if manifest.is_file():
        try:
            entries = json.loads(manifest.read_text()).get("runs", {})
        except (OSError, ValueError, AttributeError):
            entries = {}
        entry = entries.get(run.path.name) if isinstance(entries, dict) else None
        if isinstance(entry, dict):
            return spec_from_json(entry), f"{MANIFEST} entry"
    info = run.info.run
    if info is not None and info.run_spec:
        try:
            return spec_from_json(json.loads(info.run_spec)), "run specification in the metadata"
        except ValueError:
            pass  # a damaged entry: fall back to scenario, seed and first pose
    if info is None or info.seed is None or not info.scenario_file or not len(run.pose):
        raise ScenarioMismatchError(
            f"{str(run.path)!r} lacks the scenario, seed or poses needed to re-simulate it"
        )
    x, y, psi = (float(v) for v in run.pose.values[0])
    return SimRunSpec(
        scenario=info.scenario_file,
        seed=info.seed,
        start=(x, y, psi),
        loop=LoopConfig(max_duration_s=run.last_stamp_ns / NS_PER_S + 30.0),
    ), "first recorded pose (start not in the metadata)"


def check_resim(ctx: ReplayContext) -> Check:
    """Re-simulate the run with the current code and compare it with the recording.

    The trajectory is compared within ``Tolerance.resim_position_m``, the decisions
    exactly unless the re-simulation took one the other way within the boundary or
    cost-tie tolerance (:func:`hil.replay.decisions.compare_rerun_decisions`): that one is
    accepted and reported and, the closed loop then following another legitimate
    trajectory, the trajectory, decisions and tracking error are compared up to it only.
    Whether the run docked is still compared: the guarantee holds on either branch.

    The context's controllers judge a decision taken the other way; its options give
    the thresholds.
    """
    run, tolerance, controllers = ctx.run, ctx.options.tolerance, ctx.controllers
    try:
        spec, source = recorded_spec(run)
    except (ScenarioMismatchError, ValueError) as err:
        return Check("resim", Status.SKIP, str(err))
    log = MemoryLog()
    summary = run_in_sim(spec, log=log)
    est_s, ref_s = _series(log)
    decision_diffs, divergence = compare_rerun_decisions(run, log.decisions, controllers)
    # Without a divergence the whole re-simulation is compared, past the recording's end.
    est_end, out_end = compared_until(divergence, int(np.iinfo(np.int64).max))
    exact = source.endswith("entry")
    # From the first (noisy) pose the re-simulation drifts by the sensor noise: the
    # trajectory and the decisions are then compared for information only.
    drift = Status.FAIL if exact else Status.WARN
    graded: list[tuple[Status, Finding]] = []
    worst, departed = _departure(until(run.estimate, est_end), est_s, tolerance.resim_position_m)
    if departed is not None:
        graded.append((drift, departed))
    recorded_docked = any(e.code == "docked" for e in run.events)
    if summary.docked != recorded_docked:
        graded.append((Status.FAIL, Finding(
            f"recording {'docked' if recorded_docked else 'did not dock'}, re-simulation "
            f"{'docked' if summary.docked else 'did not'} ({summary.end_reason})"
        )))  # fmt: skip
    graded += [(drift, f) for f in decision_diffs]
    graded += [
        (Status.FAIL if exact else Status.WARN, f)
        for f in tracking_findings(
            "resim",
            tracking_of(until(run.estimate, out_end), until(run.reference, out_end)),
            tracking_of(until(est_s, out_end), until(ref_s, out_end)),
            tolerance.relative if exact else max(tolerance.relative, 0.25),
        )
    ]
    graded.sort(key=lambda g: g[1].t_ns if g[1].t_ns is not None else -1)
    findings = tuple(f for _, f in graded)
    metrics = {
        "start_from": source,
        "max_deviation_m": worst,
        "docked": summary.docked,
        "decision_differences": len(decision_diffs),
        "boundary_decisions": int(divergence is not None and divergence.kind == BOUNDARY),
        "cost_ties": int(divergence is not None and divergence.kind == TIE),
        "compared_until_ns": None if divergence is None else divergence.t_ns,
        "divergence": None if divergence is None else divergence.to_dict(),
    }
    note = divergence_note(divergence)
    accepted = () if divergence is None else (Finding(divergence.describe(), divergence.t_ns),)
    if not findings:
        return Check(
            "resim",
            Status.PASS,
            f"re-simulation reproduces the recording (start from {source}; "
            f"largest deviation {worst:.4f} m){note}",
            accepted,
            metrics,
        )
    return Check(
        "resim",
        Status.worst([g for g, _ in graded]),
        f"re-simulation differs from the recording, first at "
        f"{time_s(findings[0].t_ns)} (start from {source}){note}",
        findings,
        metrics,
    )


def _series(log: MemoryLog) -> tuple[Series, Series]:
    """Return a simulated run's estimates (N, 6) and velocity references (M, 3) as series."""
    est_t = np.array([e[0] for e in log.estimates], dtype=np.int64)
    est = np.array([np.concatenate([e[1], e[2]]) for e in log.estimates]).reshape(-1, 6)
    ref_t = np.array([r[0] for r in log.velocity_references], dtype=np.int64)
    ref = np.array([r[1] for r in log.velocity_references]).reshape(-1, 3)
    return Series(est_t, est), Series(ref_t, ref)


def _departure(
    recorded: Series, resim: Series, tolerance_m: float
) -> tuple[float, Finding | None]:
    """Return the largest position deviation (m) at common times, and a finding past it."""
    t, i, j = np.intersect1d(recorded.t_ns, resim.t_ns, return_indices=True)
    if not t.size:
        return math.nan, None
    deviation = np.hypot(*(resim.values[j, :2] - recorded.values[i, :2]).T)
    worst = float(deviation.max())
    if worst <= tolerance_m:
        return worst, None
    k = int(np.flatnonzero(deviation > tolerance_m)[0])
    return worst, Finding(
        f"trajectory departs from the recording by more than {tolerance_m} m "
        f"(largest {worst:.3f} m)",
        int(t[k]),
        {"max_deviation_m": worst},
    )
