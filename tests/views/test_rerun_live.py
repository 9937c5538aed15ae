"""The live Rerun log (``hil run --rerun``): every record streamed and forwarded."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rerun.chunk import RrdReader

from hil.core.tracking import tracking_error
from hil.runs.sim_run import SimRunSpec, run_in_sim
from hil.runtime.settings import LoopConfig
from hil.runtime.trace import MemoryLog
from hil.scenarios import load_scenario
from hil.views.rerun_live import LiveRerunLog
from tests.views.rrd_store import column, first, rows


def test_live_log_streams_every_record_and_forwards_it(tmp_path: Path) -> None:
    memory = MemoryLog()
    rrd = tmp_path / "live.rrd"
    live = LiveRerunLog.open(load_scenario("coarse"), save=rrd, inner=memory)
    run_in_sim(
        SimRunSpec(
            scenario="coarse",
            seed=2,
            loop=LoopConfig(resynthesis_period_s=None, max_duration_s=6.0),
        ),
        log=live,
    )
    live.close()
    store = RrdReader(rrd).store()
    assert len(memory.decisions) >= 3
    assert rows(store, "/world/vessel") == len(memory.poses)
    assert rows(store, "/world/controller/safe_inputs") == len(memory.decisions)
    assert rows(store, "/plots/velocity/surge/commanded") == len(memory.velocity_references)
    assert rows(store, "/events") == len(memory.events)
    assert rows(store, "/plots/synthesis_time_s") == memory.event_codes().count("controller_ready")
    t, scalars = column(store, "/plots/thrusters/commands", "Scalars:scalars")
    assert t.tolist() == [c.t_ns for c in memory.thruster_commands]
    want = np.array([[c.tunnel, c.port, c.starboard] for c in memory.thruster_commands])
    np.testing.assert_allclose(np.array(scalars, dtype=np.float64), want)
    # The live tracking error is the one join: each estimate against the reference in force.
    est_t = np.array([e[0] for e in memory.estimates], dtype=np.int64)
    nu = np.array([e[2] for e in memory.estimates]).reshape(-1, 3)
    ref_t = np.array([r[0] for r in memory.velocity_references], dtype=np.int64)
    nu_ref = np.array([r[1] for r in memory.velocity_references]).reshape(-1, 3)
    want_error = tracking_error(est_t, nu, ref_t, nu_ref)
    t, errors = column(store, "/plots/tracking_error/yaw_rate/error", "Scalars:scalars")
    assert t.tolist() == want_error.t_ns.tolist()
    got_error = np.array([first(e) for e in errors], dtype=np.float64)
    np.testing.assert_allclose(got_error, want_error.error[:, 2])
    # Beside it, the envelope band of the decision in force: +-bound, from the first decision.
    t, bands = column(store, "/plots/tracking_error/yaw_rate/envelope", "Scalars:scalars")
    assert t.tolist() == want_error.t_ns.tolist()
    band = np.array(bands, dtype=np.float64)
    decided = t >= memory.decisions[0].t_ns
    assert np.all(np.isnan(band[~decided]))
    assert np.all(band[decided, 0] > 0.0)
    np.testing.assert_allclose(band[decided, 1], -band[decided, 0])
