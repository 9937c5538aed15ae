"""A stalled loop: an interval longer than tau + late is a broken premise, named and failed.

Every budget (tube, successor, velocity envelope) is bounded over periods of at most tau
+ late (0.1 s). The simulated loop is stalled over a decision tick (``loop_stalls_s``:
it does not tick, the vessel moving on under its last command): 0.35 s from 5.0 s holds
the input chosen at 3.05 s for 2.30 s, 0.2 s past tau + late. The runtime names it
(``late_interval``, with the size), decides at once as a first decision, and `hil replay`
fails that interval as a broken premise with its size. A stall within the late budget
(0.08 s) is neither.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.replay.options import ReplayOptions
from hil.replay.regression import Status
from hil.replay.replayer import replay_log
from hil.runs.sim_run import SimRunSpec, simulate
from hil.runtime.settings import NS_PER_S, LoopConfig
from hil.runtime.trace import MemoryLog


def _run(stall_s: float, out_dir: Path | None = None) -> tuple[MemoryLog, SimRunSpec]:
    spec = SimRunSpec(
        "coarse", 0, out_dir=out_dir, loop=LoopConfig(max_duration_s=60.0),
        loop_stalls_s=((5.0, stall_s),),
    )  # fmt: skip
    log = MemoryLog()
    simulate(spec, None if out_dir is not None else log)
    return log, spec


def test_a_stall_within_the_late_budget_is_no_broken_premise() -> None:
    log, _ = _run(0.08)
    assert not [e for e in log.events if e[2] == "late_interval"]
    times = [d.t_ns / NS_PER_S for d in log.decisions]
    assert times[:4] == pytest.approx([1.05, 3.05, 5.08, 7.08])
    assert not log.decisions[2].first


def test_a_stall_past_the_late_budget_is_named_decided_afresh_and_fails_replay(
    tmp_path: Path,
) -> None:
    log, _ = _run(0.35)
    late = [(t, level, text) for t, level, code, text in log.events if code == "late_interval"]
    assert len(late) == 1
    t, _level, text = late[0]
    assert t == round(5.35 * NS_PER_S)
    assert "held 2.300 s, past tau + late = 2.1 s by 0.200 s" in text
    decision = next(d for d in log.decisions if d.t_ns == t)
    assert decision.first  # decided afresh, from the estimated velocity

    bag = tmp_path / "stalled"
    _run(0.35, bag)
    report = replay_log(bag, ReplayOptions(intervals=True))
    contract = next(c for c in report.checks if c.name == "contract")
    assert contract.status is Status.FAIL
    assert contract.metrics["late_intervals"] == 1
    assert contract.metrics["worst_late_s"] == pytest.approx(0.2)
    (finding,) = contract.findings
    assert finding.t_ns == round(3.05 * NS_PER_S)
    assert "past tau + late = 2.1 s by 0.200 s: a broken premise" in finding.message
    # The rest of the run replays as recorded: the stall is in the recording's ticks.
    stack = next(c for c in report.checks if c.name == "stack")
    assert stack.status is Status.PASS
    assert report.status is Status.FAIL
