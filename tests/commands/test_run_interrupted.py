"""Ctrl-C during `hil run`: a complete log, named on the console, that replays as interrupted."""

from __future__ import annotations

import dataclasses
import os
import signal
from pathlib import Path
from typing import Any, cast

import pytest

import hil.runs.sim_run
from hil.bag.run_data import load_run
from hil.cli import main
from hil.core.records import Decision
from hil.core.shapes import Rect
from hil.replay.context import ReplayContext
from hil.replay.controllers import ScenarioCache
from hil.replay.options import ReplayOptions
from hil.replay.regression import Status
from hil.replay.replayer import replay_log
from hil.replay.stop_check import check_stop
from hil.runtime.protocols import RunLog
from hil.scenarios import Scenario, load_scenario


class _CtrlCAtDecision:
    """A run log that passes everything on and sends SIGINT to this process at decision n."""

    def __init__(self, inner: RunLog, n: int) -> None:
        self._inner = inner
        self._n = n

    def decision(self, record: Decision) -> None:
        self._inner.decision(record)
        self._n -= 1
        if self._n == 0:
            os.kill(os.getpid(), signal.SIGINT)  # what Ctrl-C in the terminal sends

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


def test_ctrl_c_stops_the_run_cleanly_and_its_log_replays_as_interrupted(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    real = hil.runs.sim_run.run_in_sim

    def interrupted_at_the_third_decision(*args: Any, **kwargs: Any) -> Any:
        def live(_scenario: Scenario, inner: RunLog) -> RunLog:
            return cast(RunLog, _CtrlCAtDecision(inner, 3))

        assert kwargs.get("handle_signals") is True  # `hil run` asks for a clean stop
        return real(*args, **{**kwargs, "live": live})

    monkeypatch.setattr(hil.runs.sim_run, "run_in_sim", interrupted_at_the_third_decision)
    out = tmp_path / "run"
    assert main(["run", "coarse", "--out", str(out), "--seed", "1"]) == 1
    captured = capsys.readouterr()
    assert "NOT DOCKED" in captured.out
    assert "stopped by SIGINT" in captured.err
    assert str(out) in captured.err  # the console names the log
    # The log is complete: the stop is recorded, the vessel brakes to rest under the low
    # level (velocity reference zero), and thrust is zero from then on.
    run = load_run(out)
    stops = [e for e in run.events if e.code == "stopped"]
    assert [e.text for e in stops] == ["stopped by SIGINT"]
    (rest,) = [e for e in run.events if e.code == "at_rest"]
    assert rest.t_ns > stops[0].t_ns
    assert len(run.decisions) == 3
    braking = (run.thrusters.t_ns >= stops[0].t_ns) & (run.thrusters.t_ns < rest.t_ns)
    assert run.thrusters.values[braking, :3].any()  # braking thrust, not a coast
    refs = run.reference.t_ns >= stops[0].t_ns
    assert refs.any()
    assert not run.reference.values[refs].any()  # toward velocity zero
    after = run.thrusters.t_ns >= rest.t_ns
    assert after.any()
    assert not run.thrusters.values[after, :3].any()
    assert run.thrusters.values[~after, :3].any()  # it was under way before
    # ... and it replays through the current code without a regression, as interrupted,
    # its braking judged clear of the obstacles and walls.
    assert main(["replay", str(out)]) == 0
    replayed = capsys.readouterr().out
    assert "interrupted at" in replayed
    assert "stop: braked to rest in" in replayed
    report = replay_log(out, ReplayOptions())
    stop = next(c for c in report.checks if c.name == "stop")
    assert stop.status is Status.PASS
    assert stop.metrics["samples"] > 10
    # The same braking judged against an obstacle reported where the hull braked: FAIL.
    eta = run.estimate.values[run.estimate.t_ns >= stops[0].t_ns][0, :3]
    scenario = load_scenario("coarse")
    blocked = dataclasses.replace(run, layouts=tuple(
        dataclasses.replace(layout, rectangles=(
            Rect(float(eta[0]) - 0.1, float(eta[0]) + 0.1, float(eta[1]) - 0.1,
                 float(eta[1]) + 0.1),
        )) for layout in run.layouts
    ))
    failed = check_stop(ReplayContext(blocked, scenario, ScenarioCache()))
    assert failed.status is Status.FAIL
    assert "from an obstacle" in failed.findings[0].message
