"""What produced a run, as stored in the bag's custom_data."""

from __future__ import annotations

from hil.bag.run_info import FORMAT_VERSION, RunInfo

RUN = RunInfo("scenarios/paper.toml", "sha256:abc", 7, "0.1.0", "deadbeef", "sim")


def test_run_info_round_trip_and_foreign_data() -> None:
    assert RunInfo.from_custom_data(RUN.custom_data()) == RUN
    assert RunInfo.from_custom_data({"other": "tool"}) is None
    assert RunInfo(seed=None).custom_data()["seed"] == ""
    assert RUN.custom_data()["hil_format"] == FORMAT_VERSION
