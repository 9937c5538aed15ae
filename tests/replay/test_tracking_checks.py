"""The tracking checks on the recorded tracking error."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from hil.bag.reader import BagInfo
from hil.bag.run_data import RunData, Series
from hil.core.records import Decision
from hil.replay.context import ReplayContext
from hil.replay.controllers import ScenarioCache
from hil.replay.options import ReplayOptions, Tolerance
from hil.replay.regression import Check, Status
from hil.replay.tracking_checks import check_tracking
from hil.scenarios import load_scenario


def _synthetic_run(errors: dict[int, float]) -> RunData:
    """Estimates and references at 20 Hz for 4 s, decisions at 0 s and 2 s; surge errors."""
    t = np.arange(80, dtype=np.int64) * 50_000_000
    est = np.zeros((80, 6))
    for k, e in errors.items():
        est[k, 3] = e
    decisions = tuple(
        Decision.from_arrays(int(td), [0, 0, 0], 0, 5.0, True, [], [], -1, 1, "h")
        for td in (0, 2_000_000_000)
    )
    return RunData(
        path=Path("synthetic"),
        info=BagInfo(Path("synthetic"), "mcap", (), (), None, None),
        pose=Series.empty(3),
        imu=Series.empty(3),
        estimate=Series(t, est),
        reference=Series(t, np.zeros((80, 3))),
        force=Series.empty(3),
        thrusters=Series.empty(5),
        decisions=decisions,
        layouts=(),
        events=(),
    )


def _tracking(run: RunData, tolerance: Tolerance) -> Check:
    """The tracking check of `run` with `tolerance` (it needs no controller)."""
    options = ReplayOptions(tolerance)
    return check_tracking(ReplayContext(run, load_scenario("coarse"), ScenarioCache(), options))


def test_tracking_metrics_show_yaw_in_degrees_per_second() -> None:
    run = _synthetic_run({})
    yaw = np.zeros((80, 6))
    yaw[:, 5] = 0.01  # rad/s against a zero reference
    run = dataclasses.replace(run, estimate=Series(run.estimate.t_ns, yaw))
    check = _tracking(run, Tolerance())
    assert check.metrics["rms"] == pytest.approx([0.0, 0.0, math.degrees(0.01)])
    assert check.metrics["max_abs"][2] == pytest.approx(math.degrees(0.01))
    assert "yaw 0.57296 deg/s" in check.summary


def test_tracking_is_a_figure_unless_a_threshold_is_set() -> None:
    run = _synthetic_run(dict.fromkeys(range(80), 0.05))  # far above the paper's tank RMS
    figures = _tracking(run, Tolerance())
    assert figures.status is Status.PASS
    assert "no threshold set (the paper's tank RMS, for comparison: 0.00768" in figures.summary
    assert figures.metrics["paper_rms"] == [0.00768, 0.00431, 0.62108]
    enforced = _tracking(run, Tolerance.parse("surge=0.01"))
    assert enforced.status is Status.FAIL
    (finding,) = enforced.findings
    assert finding.data["axis"] == "surge"
    assert _tracking(run, Tolerance.parse("sway=0.01")).status is Status.PASS
