"""The resim check: a recorded run simulated again with the current code."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from hil.replay.controllers import ScenarioCache
from hil.replay.regression import Status
from hil.runs.sim_run import spec_from_json, spec_to_json
from tests.replay.suite_logs import REFERENCE, replay_unmodified


def test_spec_round_trips_through_the_manifest_form() -> None:
    from hil.commands.record_suite import suite

    for item in suite():
        assert spec_from_json(spec_to_json(item.spec)) == item.spec
    with pytest.raises(ValueError, match="malformed run specification"):
        spec_from_json({"seed": 1})


def test_resim_with_the_suite_spec_reproduces_the_recording(
    caches: ScenarioCache,
) -> None:
    resim = replay_unmodified(REFERENCE, caches, resim=True, stack=False).check("resim")
    assert resim.metrics["start_from"] == "suite.json entry"
    assert resim.status is Status.PASS, resim.findings
    # Not bit-exact across machines: numba compiles for the host CPU (FMA contraction,
    # vector width), measured at 1.5e-10 m between two x86_64 CPUs over a whole run.
    # 1 um is four orders of magnitude above that noise and below any cell (cm).
    assert resim.metrics["max_deviation_m"] < 1e-6


def test_resim_from_the_first_pose_docks_and_drift_only_warns(
    tmp_path: Path, caches: ScenarioCache
) -> None:
    copy = tmp_path / REFERENCE.name  # no suite.json beside it: start from the first pose
    shutil.copytree(REFERENCE, copy)
    resim = replay_unmodified(copy, caches, resim=True, stack=False).check("resim")
    assert resim.metrics["start_from"].startswith("first recorded pose")
    assert resim.status in (Status.PASS, Status.WARN), resim.findings
    assert resim.metrics["docked"]
    assert resim.metrics["max_deviation_m"] < 0.5
