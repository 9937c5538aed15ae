"""The tracking check, on the one tracking error of :mod:`hil.core.tracking`.

- ``tracking``: velocity-tracking error per axis (RMS, max) of the recorded
  estimates (odometry) against the recorded references. Judged only against the
  thresholds ``--tolerance`` sets (FAIL above them); otherwise the figures are
  reported beside the paper's tank figures, for comparison, and the check passes:
  the tank figures are no regression threshold (another vessel, another water).

The guarantee's velocity premise (|nu - nu_ref| within the transient budget, over the
whole interval) is judged per interval by the ``contract`` check
(:mod:`hil.replay.intervals`).

Errors are computed in SI and shown (messages, metrics) with yaw in deg/s.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hil.core.arrays import FloatArray
from hil.core.tracking import AXES, DISPLAY_UNITS, TrackingSeries, for_display
from hil.replay.context import ReplayContext
from hil.replay.regression import Check, Finding, Status
from hil.runs.summary import PAPER_TRACKING_ERROR

_AXES = AXES
_UNITS = DISPLAY_UNITS


def _metrics(series: TrackingSeries) -> dict[str, Any]:
    """Return RMS, max and time of max per axis (yaw in deg/s), JSON-ready."""
    peak, when = series.peak()
    return {
        "samples": len(series),
        "rms": [float(v) for v in for_display(series.rms())],
        "max_abs": [float(v) for v in for_display(peak)],
        "t_max_ns": [int(v) for v in when],
    }


def _axes_text(values: FloatArray) -> str:
    return ", ".join(f"{a} {v:.5f} {u}" for a, v, u in zip(_AXES, values, _UNITS, strict=True))


def check_tracking(ctx: ReplayContext) -> Check:
    """Report the recorded tracking error per axis; FAIL only above thresholds set explicitly.

    Without ``--tolerance`` thresholds the RMS and largest error are figures, shown
    beside the paper's tank RMS (``paper_rms`` in the metrics), and the check passes.
    """
    series = ctx.run.tracking_error()
    tolerance = ctx.options.tolerance
    if not len(series.t_ns):
        return Check("tracking", Status.SKIP, "no velocity references with estimates")
    rms = for_display(series.rms())
    peak_si, when = series.peak()
    peak = for_display(peak_si)
    limit = np.array(tolerance.rms)
    over = [k for k in range(3) if rms[k] > limit[k]]
    findings = [
        Finding(
            f"{_AXES[k]} RMS {rms[k]:.5f} {_UNITS[k]} > threshold {limit[k]:.5f}; "
            f"largest error {peak[k]:.4f} {_UNITS[k]}",
            int(when[k]),
            {
                "axis": _AXES[k],
                "rms": float(rms[k]),
                "threshold": float(limit[k]),
                "max_abs": float(peak[k]),
            },
        )
        for k in over
    ]
    peak_limit = np.array(tolerance.max_abs if tolerance.max_abs is not None else [math.inf] * 3)
    over_peak = [k for k in range(3) if peak[k] > peak_limit[k]]
    findings += [
        Finding(
            f"{_AXES[k]} error {peak[k]:.4f} {_UNITS[k]} > max threshold {peak_limit[k]:.4f}",
            int(when[k]),
            {"axis": _AXES[k], "max_abs": float(peak[k]), "threshold": float(peak_limit[k])},
        )
        for k in over_peak
    ]
    paper = ", ".join(f"{v:g}" for v in PAPER_TRACKING_ERROR)
    text = f"RMS {_axes_text(rms)}; max {_axes_text(peak)}"
    metrics = {
        **_metrics(series),
        "paper_rms": list(PAPER_TRACKING_ERROR),
        "threshold_rms": [float(v) for v in limit],  # inf (JSON null): none set
        "threshold_max_abs": [float(v) for v in peak_limit],
    }
    if not findings:
        judged = (
            "within thresholds"
            if tolerance.enforce_rms or tolerance.max_abs is not None
            else "no threshold set"
        )
        return Check(
            "tracking",
            Status.PASS,
            f"{text}; {judged} (the paper's tank RMS, for comparison: {paper})",
            (),
            metrics,
        )
    axes = ", ".join(sorted({_AXES[k] for k in [*over, *over_peak]}, key=_AXES.index))
    return Check(
        "tracking", Status.FAIL, f"{text}; above threshold in {axes}", tuple(findings), metrics
    )


def tracking_findings(
    name: str, recorded: TrackingSeries, replayed: TrackingSeries, relative: float
) -> list[Finding]:
    """Compare RMS and max per axis; a difference beyond `relative` is reported."""
    findings = []
    r_rms, n_rms = for_display(recorded.rms()), for_display(replayed.rms())
    (r_peak, r_when), (n_peak, n_when) = recorded.peak(), replayed.peak()
    r_max, n_max = for_display(r_peak), for_display(n_peak)
    for k in range(3):
        for what, a, b in (("RMS", r_rms[k], n_rms[k]), ("max", r_max[k], n_max[k])):
            floor = 1e-9 if _AXES[k] != "yaw" else 1e-7
            if abs(a - b) > relative * max(abs(a), abs(b)) + floor:
                when = int(r_when[k] if r_max[k] >= n_max[k] else n_when[k])
                findings.append(
                    Finding(
                        f"{name}: {_AXES[k]} tracking {what} recorded {a:.5f} {_UNITS[k]}, "
                        f"replayed {b:.5f} {_UNITS[k]}",
                        when,
                        {
                            "axis": _AXES[k],
                            "measure": what,
                            "recorded": float(a),
                            "replayed": float(b),
                        },
                    )
                )
    return findings
