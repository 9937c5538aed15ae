"""The scenario a log is replayed with, and the controllers synthesized for it."""

from __future__ import annotations

import shutil
from pathlib import Path

from hil.bag.run_data import load_run
from hil.replay.controllers import ScenarioCache, resolve_scenario
from hil.replay.regression import Status
from tests.replay.suite_logs import REFERENCE, replay_unmodified


def test_log_from_another_scenario_is_refused(tmp_path: Path, caches: ScenarioCache) -> None:
    report = replay_unmodified(REFERENCE, caches, scenario="paper")
    assert report.status is Status.ERROR
    assert "another scenario" in report.error
    copy = tmp_path / "renamed"
    shutil.copytree(REFERENCE, copy)
    meta = copy / "metadata.yaml"
    text = meta.read_text().replace('"scenario_file": "coarse"', '"scenario_file": "harbour"')
    meta.write_text(text)
    report = replay_unmodified(copy, caches)
    assert report.status is Status.ERROR
    assert "'harbour'" in report.error
    assert "cannot be loaded" in report.error


def test_resolve_scenario_checks_the_hash() -> None:
    run = load_run(REFERENCE)
    assert resolve_scenario(run).name == "coarse"
