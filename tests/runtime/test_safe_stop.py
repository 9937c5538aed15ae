"""A stop brakes the vessel to rest under the low level; thrust is cut only at rest.

An operator's stop mid-run (what SIGINT / SIGTERM ask for) puts the velocity reference to
zero and keeps the low level flying it until the estimate is at rest for 1 s; only then
do the thrusters go to zero (``at_rest``). On the simulator's true state the vessel is
then at rest, not coasting. A second request while braking cuts the thrust at once (the
emergency stop).
"""

from __future__ import annotations

import numpy as np
import pytest

from hil.adapters.sim import SimConfig, SimWorld
from hil.runs.stack_assembly import build_runtime, default_start, synthesizer_for
from hil.runtime.assembly import layout_from_scenario
from hil.runtime.loop import Runtime, World
from hil.runtime.mode import Mode
from hil.runtime.resynthesis import ResynthesisMode
from hil.runtime.settings import NS_PER_S, LoopConfig
from hil.runtime.stopping import MAX_BRAKE_S
from hil.runtime.trace import MemoryLog
from hil.scenarios import load_scenario
from hil.sim.plant import TR_NU

STOP_AT_S = 24.0  # under way at 0.15 m/s surge


def _run(second_request_after_s: float | None = None) -> tuple[Runtime, SimWorld, MemoryLog]:
    scenario = load_scenario("coarse")
    sim = SimWorld(SimConfig(start=default_start(scenario), seed=3,
                             obstacles=layout_from_scenario(scenario).obstacles),
                   max_duration_s=60.0)
    log = MemoryLog()
    runtime = build_runtime(
        scenario, World(sim.clock, sim.pose, sim.imu, sim.obstacles, sim.thrusters), log,
        LoopConfig(max_duration_s=50.0), synthesizer_for(scenario),
        ResynthesisMode.INLINE,
    )
    period = runtime.config.period_ns
    t = 0
    while runtime.mode is not Mode.STOPPED and t < 50 * NS_PER_S:
        if t == round(STOP_AT_S * NS_PER_S):
            runtime.request_stop("stopped by the test")
        if second_request_after_s is not None and t == round(
            (STOP_AT_S + second_request_after_s) * NS_PER_S
        ):
            runtime.request_stop("stopped by the test")
        runtime.tick(t)
        t += period
        sim.clock.sleep_until(t)
    return runtime, sim, log


def test_a_stop_brakes_to_rest_before_the_thrust_is_cut() -> None:
    runtime, sim, log = _run()
    assert runtime.mode is Mode.STOPPED
    codes = [(t / NS_PER_S, code) for t, _, code, _ in log.events if code in ("stopped", "at_rest")]
    assert [c for _, c in codes] == ["stopped", "at_rest"]
    stop_s, rest_s = codes[0][0], codes[1][0]
    assert stop_s == STOP_AT_S
    assert 1.0 <= rest_s - stop_s <= MAX_BRAKE_S
    assert runtime.stats.brake_s == pytest.approx(rest_s - stop_s)
    truth = sim.truth()
    t_true = truth[:, 0]
    speed = np.abs(truth[:, 1 + TR_NU : 1 + TR_NU + 3])
    moving_at_stop = speed[np.searchsorted(t_true, stop_s)]
    assert moving_at_stop[0] > 0.1  # under way when stopped: braking is needed
    # Braking thrust (not a coast) until at rest, zero only after.
    commands = [(c.t_ns / NS_PER_S, c) for c in log.thruster_commands]
    braking = [c for t, c in commands if stop_s <= t < rest_s]
    assert braking
    assert any(abs(c.port) + abs(c.starboard) + abs(c.tunnel) > 0 for c in braking)
    after = [c for t, c in commands if t >= rest_s]
    assert after
    assert all(c.port == c.starboard == c.tunnel == 0.0 for c in after)
    refs = [r for t, r in log.velocity_references if t >= stop_s * NS_PER_S]
    assert refs
    assert np.all(np.array(refs) == 0.0)
    # At rest on the true state when the thrust was cut.
    at_rest = speed[np.searchsorted(t_true, rest_s)]
    assert at_rest[0] < 0.02
    assert at_rest[1] < 0.02
    assert at_rest[2] < 0.02


def test_a_second_stop_request_while_braking_cuts_the_thrust_at_once() -> None:
    runtime, _, log = _run(second_request_after_s=0.5)
    assert runtime.mode is Mode.STOPPED
    texts = [(t / NS_PER_S, text) for t, _, code, text in log.events if code == "stopped"]
    assert texts[0] == (STOP_AT_S, "stopped by the test")
    assert texts[1][0] == STOP_AT_S + 0.5
    assert "again while braking: thrust cut at once" in texts[1][1]
    assert not [code for _, _, code, _ in log.events if code == "at_rest"]
    last = log.thruster_commands[-1]
    assert last.t_ns == round((STOP_AT_S + 0.5) * NS_PER_S)
    assert last.port == last.starboard == last.tunnel == 0.0
