"""Poses noisier than the EKF's model: the estimation premise breaks, is named, stops the run.

The guarantee assumes the estimate within the estimation bound of the truth, a bound
measured with the motion capture's 1 mm / 0.1 deg noise that the EKF models. With the
simulated poses 3 times noisier (``pose_noise_scale``), the EKF's innovations leave its
model within the first window: the runtime names it (``estimate_inconsistent``, with the
figures), brakes to rest and ends the run aborted; `hil replay` fails the run's
estimation check, from its own re-run of the filter on the recorded samples and from the
vessel's event. With the model's noise, the same check passes with its margin.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.replay.options import ReplayOptions
from hil.replay.regression import Status
from hil.replay.replayer import replay_log
from hil.runs.sim_run import SimRunSpec, simulate
from hil.runtime.settings import LoopConfig


def _spec(scale: float, out_dir: Path) -> SimRunSpec:
    return SimRunSpec(
        "coarse", 0, out_dir=out_dir, loop=LoopConfig(max_duration_s=60.0),
        pose_noise_scale=scale,
    )  # fmt: skip


@pytest.fixture(scope="module")
def noisy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    bag = tmp_path_factory.mktemp("estimation") / "noisy"
    outcome = simulate(_spec(3.0, bag))
    assert outcome.summary.aborted
    assert outcome.stats.estimate_inconsistent_ns is not None
    return bag


def test_noisy_poses_stop_the_run_with_the_premise_named(noisy: Path) -> None:
    report = replay_log(noisy, ReplayOptions(stack=False, resim=False))
    check = next(c for c in report.checks if c.name == "estimation")
    assert check.status is Status.FAIL
    assert "estimation premise broke" in check.summary
    messages = [f.message for f in check.findings]
    assert any(m.startswith("re-run: estimation premise broken (NIS") for m in messages)
    assert any(m.startswith("on the vessel: estimation premise broken") for m in messages)
    assert check.metrics["worst_mean_nis"] > 20.0  # the model's 3 times 9
    stop = next(c for c in report.checks if c.name == "stop")
    assert stop.status is Status.PASS  # braked to rest, clear of everything
    assert report.status is Status.FAIL


def test_the_model_s_noise_keeps_the_premise(tmp_path: Path) -> None:
    bag = tmp_path / "nominal"
    outcome = simulate(_spec(1.0, bag))
    assert outcome.summary.docked
    assert outcome.stats.estimate_inconsistent_ns is None
    report = replay_log(bag, ReplayOptions(stack=False, resim=False))
    check = next(c for c in report.checks if c.name == "estimation")
    assert check.status is Status.PASS
    assert 2.5 < check.metrics["worst_mean_nis"] < 4.31
