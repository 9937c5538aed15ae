"""A solver slower than its obstacle reports: the report age measured, not stated.

The coarse scenario with O2 (shortened to y in [0.5, 3] m) tracked at 0.05 m/s and moving
up at that speed from 2 s to 8 s, reported every 0.5 s; each synthesis takes 1 s of
simulated time, one at a time (``SimRunSpec.synthesis_latency_s``, as a vessel's solver
beside its loop). With the stated 1-s age, controllers arrive older than they were solved
for and the vessel stops (``obstacles_stale``); with ``report_age = "measured"`` each
layout is solved for the age the runtime measured, the vessel is never stopped as stale,
docks, and its true hull never touches the moving obstacle. The recorded run replays with
the same verdict: every decision's controller solved again for the age it recorded, the
stack re-run with the same simulated latency.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hil import scenarios
from hil.bag.run_data import load_run
from hil.replay.options import ReplayOptions
from hil.replay.regression import Status
from hil.replay.replayer import replay_log
from hil.runs.sim_run import SimRunSpec, simulate
from hil.runtime.settings import LoopConfig
from hil.runtime.trace import MemoryLog

LATENCY_S = 1.0
START = (0.0, -1.2, 3.14159)
MOTION = """
[[simulated_motion]]
obstacle = "O2"
velocity_mps = [0.0, 0.05]
start_s = 2.0
stop_s = 8.0

[sim]
obstacle_report_period_s = 0.5
"""


def _scenario(folder: Path, report_age: str) -> str:
    text = (Path(scenarios.__file__).parent / "coarse.toml").read_text()
    edits = {
        "position_tolerance_m = 0.01": f'position_tolerance_m = 0.01\nreport_age = "{report_age}"',
        'name = "O2"\nx_m = [-1.25, -0.75]\ny_m = [0.0, 3.0]\n': (
            'name = "O2"\nx_m = [-1.25, -0.75]\ny_m = [0.5, 3.0]\nmax_speed_mps = 0.05\n'
        ),
    }
    for old, new in edits.items():
        assert old in text
        text = text.replace(old, new, 1)
    path = folder / f"coarse-o2-moving-{report_age}.toml"
    path.write_text(text + MOTION)
    return str(path)


def _spec(scenario: str, out_dir: Path | None = None) -> SimRunSpec:
    return SimRunSpec(
        scenario, 0, START, out_dir=out_dir, loop=LoopConfig(max_duration_s=90.0),
        synthesis_latency_s=LATENCY_S,
    )  # fmt: skip


@pytest.mark.slow
def test_a_measured_report_age_keeps_a_slow_solver_from_stale_stops(tmp_path: Path) -> None:
    stated = simulate(_spec(_scenario(tmp_path, "stated")))
    # The defect: solved for 1 s, every controller of a moved layout arrives >= 1 s old.
    assert stated.stats.obstacle_stale_stops >= 1

    log = MemoryLog()
    measured_toml = _scenario(tmp_path, "measured")
    out = simulate(_spec(measured_toml), log)
    s = out.summary
    assert s.docked
    assert s.obstacle_stale_stops == 0
    assert not [e for e in log.events if e[2] in ("obstacles_stale", "synthesis_overrun")]
    # Judged on the simulator's true state against the moving O2: no contact, and the
    # runtime's own promises kept.
    assert s.hull_contacts == 0
    assert s.min_clearance_m > 0.0
    assert (s.tube_exits, s.successor_misses, s.value_not_decreasing) == (0, 0, 0)
    # The ages: measured, recorded with every decision, each decision relying on a report
    # no older than its own (the newest report taken in at or before it).
    ages = {d.report_age_s for d in log.decisions}
    assert None not in ages
    assert max(a for a in ages if a is not None) > 1.0
    assert s.report_age_solved_s == max(a for a in ages if a is not None)
    assert s.report_age_relied_s > LATENCY_S
    for d in log.decisions:
        newest = max(layout.t_ns for layout in log.layouts if layout.t_ns <= d.t_ns)
        assert d.report_age_s is not None
        assert (d.t_ns - newest) / 1e9 <= d.report_age_s

    # Recorded and replayed: the same verdict.
    bag = tmp_path / "bag"
    recorded = simulate(_spec(measured_toml, bag))
    assert recorded.summary.docked
    run = load_run(bag)
    assert [d.report_age_s for d in run.decisions] == [d.report_age_s for d in log.decisions]
    report = replay_log(bag, ReplayOptions())
    statuses = {c.name: c.status for c in report.checks}
    assert report.status is Status.PASS, statuses
    assert statuses["stack"] is Status.PASS
