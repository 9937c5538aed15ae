"""`hil vessel --print-config`: every key, its value and its meaning, as TOML that loads back."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from hil.cli import main
from hil.core.config import from_table
from hil.runs.vessel_config import VesselConfig


def _printed(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    assert main(["vessel", "--print-config", *args]) == 0
    return capsys.readouterr().out


def test_the_defaults_print_as_toml_that_loads_back(capsys: pytest.CaptureFixture[str]) -> None:
    text = _printed(capsys)
    assert from_table(VesselConfig, tomllib.loads(text)) == VesselConfig()
    keys = [line for line in text.splitlines() if " = " in line and not line.startswith("#")]
    assert len(keys) >= 25
    # Every key says what it means (its field's entry in the class docstring).
    assert all("  # " in line or " # " in line for line in keys), [
        line for line in keys if " # " not in line
    ]
    assert "pose_frame_id = \"world_ned\"" in text
    assert "# [qtm]" in text
    assert "# host = (unset)" in text


def test_a_config_file_prints_as_itself(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    config = tmp_path / "vessel.toml"
    config.write_text("""
scenario = "coarse"
[ros]
pose_frame_id = "map"
best_effort_sensors = true
[ros.transform]
yaw_rad = 0.5
[loop]
max_duration_s = 90.0
[qtm]
host = "qtm.lab"
body = "voyager"
""")
    text = _printed(capsys, "--config", str(config))
    again = tmp_path / "printed.toml"
    again.write_text(text)
    assert VesselConfig.load(again) == VesselConfig.load(config)
    assert 'host = "qtm.lab"' in text
    assert "[qtm.transform]" not in text


def test_without_a_config_the_command_says_what_is_missing(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["vessel"]) == 2
    err = capsys.readouterr().err
    assert "hil vessel: error:" in err
    assert "--config FILE" in err
    assert "--print-config" in err
