"""The QTM check: the recorded arena pose is the recorded QTM frame mapped through the transform.

A run with the qtm pose backend records each 6D frame as received (``/hil/qtm/6d``,
:class:`~hil.core.qtm_sample.QtmSample`) beside the arena pose the stack used
(``/hil/pose``) and the transform (``/tf_static``). ``qtm``: every frame in which QTM
saw the body is mapped again as the backend maps it (:func:`~hil.adapters.qtm_feed.
lab_pose_from_6d`, then :meth:`~hil.core.arena_frame.ArenaTransform.to_arena`) and
compared with the recorded pose of the same stamp: FAIL when one differs by more than
:data:`POSITION_TOLERANCE_M` or :data:`YAW_TOLERANCE_RAD`. The metrics keep QTM's
frames, the body losses, the frame-number drops and QTM's own drop rates. Made only
for runs that hold QTM frames.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hil.adapters.qtm_feed import lab_pose_from_6d
from hil.bag.run_data import RunData
from hil.core.geometry import wrap_angle
from hil.core.qtm_sample import QtmSample
from hil.replay.context import ReplayContext
from hil.replay.regression import Check, Finding, Status

POSITION_TOLERANCE_M = 1e-9
"""Largest |recorded - remapped| arena position (m): the recorder stores doubles, the yaw
through a quaternion, so the two agree to ~1e-15 m; anything above is another mapping."""
YAW_TOLERANCE_RAD = 1e-9
"""Largest |recorded - remapped| heading (rad), the same reasoning."""
_SHOWN = 5


def has_qtm(run: RunData) -> bool:
    """Whether the run holds QTM 6D frames (the check applies)."""
    return bool(run.qtm)


def qtm_metrics(frames: tuple[QtmSample, ...]) -> dict[str, Any]:
    """Return what QTM sent, counted: frames, seen, lost, drops, QTM's drop fields."""
    seen = sum(1 for s in frames if s.seen)
    return {
        "frames": len(frames),
        "seen": seen,
        "lost": len(frames) - seen,
        "drops": max((s.drops for s in frames), default=0),
        "max_drop_rate": max((s.drop_rate for s in frames), default=0),
        "max_out_of_sync_rate": max((s.out_of_sync_rate for s in frames), default=0),
        "first_frame": frames[0].frame_number if frames else None,
        "last_frame": frames[-1].frame_number if frames else None,
    }


def check_qtm(ctx: ReplayContext) -> Check:
    """The replay's ``qtm`` check (:func:`judge_qtm` of the context's run)."""
    return judge_qtm(ctx.run)


def judge_qtm(run: RunData) -> Check:
    """Compare each recorded arena pose with its QTM frame mapped through the transform."""
    metrics = qtm_metrics(run.qtm)
    if run.lab_frame is None:
        return Check("qtm", Status.SKIP, "QTM frames but no /tf_static: no transform to "
                     "map them with", metrics=metrics)  # fmt: skip
    transform = run.lab_frame.transform
    pose_t, poses = run.pose.t_ns, run.pose.values
    findings: list[Finding] = []
    matched = unmatched = 0
    worst_m = worst_rad = 0.0
    for sample in run.qtm:
        lab = lab_pose_from_6d(sample.t_ns, sample.position_mm, sample.rotation)
        if lab is None:
            continue
        k = int(np.searchsorted(pose_t, sample.t_ns))
        if k >= len(pose_t) or pose_t[k] != sample.t_ns:
            unmatched += 1
            continue
        matched += 1
        want = transform.to_arena(lab)
        d_m = math.hypot(poses[k, 0] - want.x_m, poses[k, 1] - want.y_m)
        d_rad = abs(wrap_angle(poses[k, 2] - want.yaw_rad))
        worst_m, worst_rad = max(worst_m, d_m), max(worst_rad, d_rad)
        if (d_m > POSITION_TOLERANCE_M or d_rad > YAW_TOLERANCE_RAD) and len(findings) < _SHOWN:
            findings.append(Finding(
                f"frame {sample.frame_number}: recorded pose is {d_m:.3g} m, {d_rad:.3g} rad "
                "from the QTM frame mapped through /tf_static", sample.t_ns,
                {"recorded": poses[k].tolist(), "qtm": [want.x_m, want.y_m, want.yaw_rad]}))
    metrics |= {"matched": matched, "unmatched": unmatched, "max_position_error_m": worst_m,
                "max_yaw_error_rad": worst_rad}  # fmt: skip
    counts = (f"{metrics['frames']} QTM frames, {metrics['lost']} with the body lost, "
              f"{metrics['drops']} dropped")  # fmt: skip
    if findings:
        return Check("qtm", Status.FAIL, f"{counts}: recorded poses differ from QTM's frames "
                     f"(worst {worst_m:.3g} m, {worst_rad:.3g} rad)", tuple(findings), metrics)
    if not matched and metrics["seen"]:
        return Check("qtm", Status.WARN, f"{counts}: no recorded pose at a QTM frame's stamp",
                     metrics=metrics)  # fmt: skip
    return Check("qtm", Status.PASS, f"{counts}; {matched} recorded poses equal their frame "
                 f"mapped through /tf_static (within {POSITION_TOLERANCE_M:g} m, "
                 f"{YAW_TOLERANCE_RAD:g} rad)", metrics=metrics)  # fmt: skip
