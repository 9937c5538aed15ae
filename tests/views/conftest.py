"""The export of a real short run, shared by the Rerun view tests.

The run is a real simulated docking on the coarse scenario with one obstacle
moving (so the layout changes and the controller is re-synthesized once). The
``.rrd`` is read back with ``rerun.chunk.RrdReader``.
"""

from __future__ import annotations

import pytest
from rerun.chunk import RrdReader

from hil.adapters.sim import ObstacleMotion
from hil.bag.run_data import load_run
from hil.runs.sim_run import SimRunSpec, run_in_sim
from hil.runtime.settings import LoopConfig
from hil.views.controller_view import controller_view, scenario_for
from hil.views.rerun_export import write_rrd
from tests.views.rrd_store import Exported


@pytest.fixture(scope="session")
def exported(tmp_path_factory: pytest.TempPathFactory) -> Exported:
    root = tmp_path_factory.mktemp("rerun")
    bag = root / "run"
    # O2 moves 0.1 m at t = 1..1.5 s: two layouts, one re-synthesis.
    run_in_sim(
        SimRunSpec(
            scenario="coarse",
            seed=3,
            out_dir=bag,
            motions=(ObstacleMotion(index=0, velocity_mps=(0.2, 0.0), start_s=1.0, stop_s=1.5),),
            loop=LoopConfig(resynthesis_period_s=None, max_duration_s=12.0),
        )
    )
    run = load_run(bag)
    scenario, note = scenario_for(run)
    assert scenario is not None, note
    rrd = root / "run.rrd"
    write_rrd(run, rrd, scenario, controller_view(run, scenario))
    return Exported(bag, run, scenario, rrd, RrdReader(rrd).store())
