"""`hil run` says its stage from the run's records, and its summary where controllers came from."""

from __future__ import annotations

import pytest
from rich.console import Console

from hil.commands.run_progress import StageLog
from hil.core.records import ControllerReady, ControllerSource
from hil.core.samples import PoseSample
from hil.runs.sim_run import SimRunSpec, run_in_sim
from hil.runtime.settings import LoopConfig
from hil.runtime.trace import MemoryLog


def _ready(
    t_ns: int, version: int, source: ControllerSource, complete: bool = True
) -> ControllerReady:
    return ControllerReady(t_ns, version, 0.1, source, complete, 0.0, -1)


def test_stage_log_says_the_stage_and_passes_every_record_on() -> None:
    shown: list[str] = []
    inner = MemoryLog()
    log = StageLog(inner, shown.append, "coarse, seed 0")
    assert shown[-1] == "coarse, seed 0: synthesizing the first controller (or reading the store)"
    log.pose(PoseSample(1_000_000_000, 0.0, 0.0, 0.0))
    log.controller_ready(_ready(1_000_000_000, 1, ControllerSource.STORE))
    log.controller_ready(_ready(3_000_000_000, 2, ControllerSource.SOLVED, complete=False))
    log.controller_ready(_ready(3_500_000_000, 2, ControllerSource.MEMORY))
    assert shown[-1] == (
        "coarse, seed 0: docking, 2.5 s simulated, 0 decisions, 2 controllers (1 stored, 1 memory)"
    )
    assert len(inner.controllers) == 3
    assert len(inner.poses) == 1


@pytest.fixture(scope="module")
def short_run() -> object:
    return run_in_sim(SimRunSpec(scenario="coarse", seed=1, loop=LoopConfig(max_duration_s=6.0)))


def test_the_summary_separates_solves_from_controllers_served_from_memory(
    short_run: object,
) -> None:
    from hil.runs.summary import RunSummary

    assert isinstance(short_run, RunSummary)
    assert short_run.sources is not None
    assert short_run.sources.total() == short_run.resyntheses >= 2
    console = Console(record=True, width=200)
    short_run.render(console)
    text = console.export_text()
    src = short_run.sources
    assert (
        f"{short_run.decisions} / {short_run.resyntheses}: {src.solved} solved, "
        f"{src.store} from the store, {src.memory} from memory"
    ) in text
    assert "re-syntheses" not in text
