"""Replay of a lab bag: the stack re-run on the lab's own topics, judged on what the bag holds.

A bag recorded on the tank by the lab's stack (``ros2 bag record``) holds the lab's
``/voyager/...`` topics only (:mod:`hil.bag.lab_streams`): no decisions, no
obstacle layouts, no events, no hil metadata. Replayed with ``--scenario``:

- ``stack``: the full stack (EKF, symbolic decisions, PID, allocation) re-run on the
  bag's pose and IMU, ticking at the loop rate over the bag's span, against the
  scenario's obstacle layout held fixed; its decisions go into the report (the
  judged intervals, ``--jsonl``, ``--json``) and into the ``.rrd`` (``--rerun``).
  Figures beside them: the re-run estimate against the bag's odometry, and the
  re-run's velocity references against the bag's velocity commands. WARN only when
  the first decision found no safe input (the start outside the scenario's winning
  set: a wrong scenario or arena transform, something to act on).
- ``tracking``: the bag's velocity commands against its odometry, or against the
  re-run estimate when the bag holds no odometry; SKIP without velocity commands.
- ``contract``: the re-run decisions' contracts judged on the re-run estimate, only
  when the vessel flew them (the bag's velocity commands are the re-run's references
  within :data:`FLEW_TOLERANCE` at :data:`FLEW_SHARE` of the samples); else SKIP.
- ``decisions``: SKIP, and :data:`NOT_JUDGED` lists what cannot be judged without
  hil's own topics.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from hil.adapters.frames import ArenaTransform
from hil.bag import topics
from hil.bag.errors import ReplayError
from hil.bag.lab_streams import LabTopics, PoseMap
from hil.bag.run_data import Layout, RunData, Series
from hil.core.arrays import FloatArray, IntArray
from hil.core.clock import NS_PER_S
from hil.core.geometry import wrap_angles
from hil.core.records import Decision
from hil.core.timeline import in_force
from hil.core.tracking import AXES, DISPLAY_UNITS, for_display
from hil.replay.context import ReplayContext
from hil.replay.intervals import check_contract
from hil.replay.regression import Check, Finding, Interval, Status, time_s
from hil.replay.stack_rerun import Rerun, rerun_stack
from hil.replay.tracking_checks import check_tracking
from hil.runs.vessel_config import VesselConfig
from hil.runtime.assembly import layout_from_scenario
from hil.runtime.settings import LoopConfig
from hil.scenarios import Scenario

NOT_JUDGED = (
    "recorded decisions (no /hil/decision): whether the vessel's controller decided as the "
    "current code does, and every field of its decisions",
    "the contract of the decisions the vessel actually flew, unless its velocity commands "
    "are the re-run's (then judged on the re-run estimate)",
    "obstacle motion (no /hil/obstacles): the scenario's layout is taken as fixed",
    "whether the stack reproduces the vessel's estimates and thruster commands (the bag's "
    "came from the lab's stack); faults and stops the vessel logged (no /hil/events)",
)
"""What a lab bag cannot tell without hil's own topics, one line each."""

FLEW_TOLERANCE = 1e-3
"""Largest |command - re-run reference| per axis (m/s, rad/s) counted as the same command.

Far below one input-grid step (0.05 m/s, 0.05 rad/s on the packaged scenarios), far
above the float rounding of a recorded double."""
FLEW_SHARE = 0.95
"""Share of the bag's velocity commands that must match the re-run's references for the
vessel to count as having flown the re-run decisions (the rest: the start before the
first decision, a late command at a decision's tick)."""


def pose_map(transform: ArenaTransform) -> PoseMap:
    """Return the vectorized :meth:`ArenaTransform.to_arena` of lab poses (N, 3) (n, e, yaw)."""
    return transform.poses_to_arena


def lab_topics(config: VesselConfig | None = None, source: str = "") -> LabTopics:
    """Return where the lab's streams are and how its poses map to the arena.

    Args:
        config: The vessel config (topic names, ``[ros.transform]``); None: the lab's
            defaults (VESSEL.md) and the identity transform.
        source: Where the config came from, for the reports.
    """
    if config is None:
        return LabTopics(
            pose_to_arena=pose_map(ArenaTransform()),
            transform_note="identity transform, the vessel config's default; --config FILE "
            "for the vessel's [ros.transform]",
        )
    t = config.ros.topics
    return LabTopics(
        pose=t.pose,
        imu=t.imu,
        tunnel=t.tunnel,
        port=t.port,
        starboard=t.starboard,
        pose_to_arena=pose_map(config.ros.transform),
        transform_note=f"[ros.transform] of {source or 'the vessel config'}",
    )


def load_lab_config(path: Path | None) -> tuple[LabTopics, LoopConfig]:
    """Read the vessel config at `path` (None: defaults) for a lab bag's topics and loop.

    Raises:
        ValueError: The config cannot be read (naming the key or the file).
    """
    if path is None:
        return lab_topics(), LoopConfig()
    try:
        config = VesselConfig.load(path)
    except OSError as err:
        raise ValueError(f"cannot read vessel config {str(path)!r}: {err.strerror or err}") from err
    return lab_topics(config, str(path)), config.loop


def with_scenario_layout(run: RunData, scenario: Scenario) -> RunData:
    """Return `run` with the scenario's obstacles as its one layout, from its first stamp."""
    layout = layout_from_scenario(scenario, 0)
    real = tuple(np.asarray(o.shape.vertices(), dtype=np.float64) for o in scenario.obstacles)
    return dataclasses.replace(
        run, layouts=(Layout(min(run.start_ns, 0), real, (), layout.obstacles),)
    )


def lab_ticks(run: RunData, loop: LoopConfig) -> IntArray:
    """Return the re-run's ticks (ns): the loop period from the bag's first pose to its last sample.

    hil's own loop ticks the same way from its first pose, so a lab bag converted from a
    hil log ticks where the recording did.
    """
    first = int(run.pose.t_ns[0])
    last = max(int(run.pose.t_ns[-1]), int(run.imu.t_ns[-1]) if len(run.imu) else 0)
    period = round(NS_PER_S / loop.loop_hz)
    return np.arange(first, last + 1, period, dtype=np.int64)


def _held(series: Series, t_ns: IntArray) -> tuple[IntArray, FloatArray]:
    """Return the samples of `series` in force at `t_ns` (those after its first sample)."""
    k = in_force(series.t_ns, t_ns)
    has = k >= 0
    return t_ns[has], series.values[k[has]]


def flown_share(commands: Series, references: Series) -> float | None:
    """Share of the bag's velocity commands equal (within FLEW_TOLERANCE) to the re-run's.

    Each command is compared with the re-run's reference in force at its time; None
    when either stream is empty or no command comes after the first reference.
    """
    if not len(commands) or not len(references):
        return None
    t, ref = _held(references, commands.t_ns)
    if not len(t):
        return None
    cmd = commands.values[np.isin(commands.t_ns, t)]
    return float(np.mean(np.abs(cmd - ref).max(axis=1) <= FLEW_TOLERANCE))


def _estimate_figures(run: RunData, estimate: Series) -> str:
    """One line: the re-run estimate (held) against the bag's odometry, RMS per field."""
    if not len(run.estimate) or not len(estimate):
        return ""
    after = run.estimate.t_ns >= estimate.t_ns[0]
    if not after.any():
        return ""
    _, held = _held(estimate, run.estimate.t_ns[after])
    diff = held - run.estimate.values[after]
    diff[:, 2] = wrap_angles(diff[:, 2])
    pos = float(np.sqrt(np.mean(np.sum(diff[:, :2] ** 2, axis=1))))
    psi = float(np.degrees(np.sqrt(np.mean(diff[:, 2] ** 2))))
    vel = for_display(np.sqrt(np.mean(diff[:, 3:6] ** 2, axis=0)))
    axes = ", ".join(f"{a} {v:.4f} {u}" for a, v, u in zip(AXES, vel, DISPLAY_UNITS, strict=True))
    return (
        f"re-run estimate vs the bag's odometry ({topics.ODOM}), RMS: position {pos:.4f} m, "
        f"heading {psi:.3f} deg, {axes}"
    )


def _decision_finding(d: Decision) -> Finding:
    state = [round(v, 3) for v in d.state]
    chosen = [round(v, 3) for v in d.chosen_input]
    what = (
        f"chose input {d.chosen_index} {chosen} of {len(d.safe_input_indices)} safe"
        if d.chosen_index >= 0
        else ("in the target" if d.value == 0.0 else "no safe input")
    )
    return Finding(
        f"decision at {state}: cell {d.cell}, value {d.value:g}, {what}",
        d.t_ns,
        {
            "state": list(d.state),
            "cell": d.cell,
            "value": d.value,
            "winning": d.winning,
            "safe": list(d.safe_input_indices),
            "chosen": d.chosen_index,
            "chosen_input": list(d.chosen_input),
            "first": d.first,
        },
    )


def _stack_check(run: RunData, rerun: Rerun, loop: LoopConfig, flown: float | None) -> Check:
    decisions = rerun.log.decisions
    estimate = rerun.estimates()
    figures = [f for f in (_estimate_figures(run, estimate),) if f]
    if flown is not None:
        figures.append(
            f"the bag's velocity commands ({topics.VELOCITY_COMMAND}) equal the re-run's "
            f"references at {100 * flown:.1f} % of the samples"
        )
    winning = sum(d.winning for d in decisions)
    metrics = {
        "ticks": len(estimate),
        "loop_hz": loop.loop_hz,
        "decisions": len(decisions),
        "winning_decisions": winning,
        "end_reason": rerun.stats.end_reason,
        "flown_share": flown,
        "figures": figures,
        "replayed_decisions": [_decision_finding(d).to_dict() for d in decisions],
    }
    findings = tuple(_decision_finding(d) for d in decisions)
    head = (
        f"re-run on the bag's pose and IMU ({len(estimate)} ticks at {loop.loop_hz:g} Hz, the "
        f"scenario's layout held fixed): {len(decisions)} decisions, {winning} winning"
    )
    if decisions:
        head += f", first at {time_s(decisions[0].t_ns)}"
    if rerun.stats.docked_ns is not None:
        head += f"; docked at {time_s(rerun.stats.docked_ns)}"
    summary = "; ".join([head, *figures])
    if decisions and not decisions[0].winning:
        return Check(
            "stack",
            Status.WARN,
            f"{summary}; the first decision found no safe input: the bag's start lies "
            "outside the scenario's winning set (check --scenario and the arena transform)",
            findings,
            metrics,
        )
    return Check("stack", Status.PASS, summary, findings, metrics)


def require_pose(run: RunData) -> None:
    """Raise unless the lab bag holds poses.

    Raises:
        ReplayError: It holds none: the stack cannot run without the motion-capture pose.
    """
    if not len(run.pose):
        raise ReplayError(
            f"{str(run.path)!r} holds only the lab's topics and no pose on {topics.POSE!r}: "
            "the stack cannot be re-run without the motion-capture pose (nothing judged)"
        )


def replay_lab(
    ctx: ReplayContext, loop: LoopConfig
) -> tuple[list[Check], tuple[Interval, ...], tuple[Decision, ...]]:
    """Replay a lab bag (module docstring); return its checks, intervals and re-run decisions.

    Its checks are the replayer's where they apply (tracking, contract), made on the
    re-run's view of the bag.

    Raises:
        ReplayError: The bag holds no pose (the stack cannot run without one).
    """
    require_pose(ctx.run)
    run = with_scenario_layout(ctx.run, ctx.scenario)
    ctx = ctx.on(run)
    rerun = rerun_stack(run, ctx.controllers, ctx.options, lab_ticks(run, loop), loop)
    decisions = tuple(rerun.log.decisions)
    references = rerun.references()
    flown = flown_share(run.reference, references)
    checks = [
        Check(
            "decisions",
            Status.SKIP,
            "not judged: the bag holds no recorded decisions (/hil/decision); the re-run's "
            "are under stack",
        ),
        _stack_check(run, rerun, loop, flown),
    ]
    estimate = rerun.estimates()
    if not len(run.reference):
        checks.append(
            Check(
                "tracking",
                Status.SKIP,
                f"not judged: the bag holds no velocity command ({topics.VELOCITY_COMMAND})",
            )
        )
    else:
        source = run if len(run.estimate) else dataclasses.replace(run, estimate=estimate)
        tracking = check_tracking(ctx.on(source))
        what = (
            f"the bag's odometry ({topics.ODOM})"
            if len(run.estimate)
            else "the re-run estimate (the bag holds no odometry)"
        )
        checks.append(
            dataclasses.replace(
                tracking, summary=f"velocity commands vs {what}: {tracking.summary}"
            )
        )
    # The contract, judged on the re-run decisions and estimate, with the references
    # the vessel was given (the bag's commands when it has them).
    judged_run = dataclasses.replace(
        run,
        decisions=decisions,
        estimate=estimate,
        reference=run.reference if len(run.reference) else references,
        events=(),
    )
    contract = check_contract(ctx.on(judged_run).after(tuple(checks)))
    intervals = contract.intervals
    if flown is not None and flown >= FLEW_SHARE:
        checks.append(contract)
    else:
        why = (
            "the bag holds no velocity command"
            if flown is None
            else f"the vessel did not fly the re-run's decisions (its velocity commands "
            f"equal the re-run's references at {100 * flown:.1f} % of the samples, "
            f"under {100 * FLEW_SHARE:g} %)"
        )
        checks.append(Check("contract", Status.SKIP, f"not judged: {why}"))
        intervals = tuple(
            dataclasses.replace(i, status=Status.SKIP, notes=(f"not judged: {why}",))
            for i in intervals
        )
    return checks, intervals, decisions


__all__ = [
    "FLEW_SHARE",
    "FLEW_TOLERANCE",
    "NOT_JUDGED",
    "flown_share",
    "lab_ticks",
    "lab_topics",
    "load_lab_config",
    "pose_map",
    "replay_lab",
    "require_pose",
    "with_scenario_layout",
]
