from pathlib import Path

import pytest

from hil.adapters.ros import RosConfig
from hil.core.config import ConfigError, check_keys, from_table, load_toml, number, numbers, table
from hil.runs.vessel_config import VesselConfig


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "vessel.toml"
    path.write_text(text)
    return path


def test_full_vessel_config_round_trips_into_dataclasses(tmp_path: Path) -> None:
    config = VesselConfig.load(_write(tmp_path, """
scenario = "coarse"
runs_dir = "/data/runs"
[ros]
use_sim_time = true
domain_id = 7
[ros.topics]
pose = "/other/pose"
[ros.transform]
origin_north_m = 1.5
yaw_rad = 0.25
[loop]
loop_hz = 25
pose_timeout_s = 0.3
synthesis_threads = 3
"""))
    assert config.scenario == "coarse"
    assert config.ros.domain_id == 7
    assert config.ros.use_sim_time is True
    assert config.ros.topics.pose == "/other/pose"
    assert config.ros.topics.imu == "/voyager/measurement/imu"  # default kept
    assert config.ros.transform.origin_north_m == 1.5
    assert config.loop.loop_hz == 25.0
    assert isinstance(config.loop.loop_hz, float)
    assert config.loop.synthesis_threads == 3


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('[ros]\nqos_depht = 3\n', r"unknown key ros.'qos_depht'"),
        ('[loop]\nloop_hz = "fast"\n', r"loop.'loop_hz' must be a finite number"),
        ('[loop]\nloop_hz = -5.0\n', r"loop_hz.*must be positive"),
        ('[loop]\nsynthesis_threads = 0\n', r"synthesis_threads.*whole number >= 1, got 0"),
        ('[ros]\ndomain_id = 1.5\n', r"ros.'domain_id' must be an integer"),
        ('[ros]\nuse_sim_time = 1\n', r"ros.'use_sim_time' must be true or false"),
        ('[ros.transform]\nyaw_rad = nan\n', r"ros.transform.'yaw_rad' must be a finite number"),
        ("ros = 3\n", r"'ros' must be a table"),
        ("scenario = \n", r"not valid TOML"),
    ],
)
def test_bad_config_names_the_key(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        VesselConfig.load(_write(tmp_path, text))


def test_missing_file_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="does not exist"):
        load_toml(tmp_path / "nope.toml")


def test_nested_defaults_without_tables() -> None:
    assert from_table(RosConfig, {}) == RosConfig()


def test_key_checks_name_the_key_like_from_table() -> None:
    data = {"cell_m": [0.05, "x"], "tau_s": True, "extra_m": 1.0}
    with pytest.raises(ConfigError, match=r"grid.'cell_m' must be a list of 2 finite numbers"):
        numbers(data, "cell_m", "grid.", 2)
    with pytest.raises(ConfigError, match=r"timing.'tau_s' must be a finite number"):
        number(data, "tau_s", "timing.")
    with pytest.raises(ConfigError, match=r"missing key grid.'size_m'"):
        number(data, "size_m", "grid.")
    assert number(data, "size_m", "grid.", 2.5) == 2.5
    with pytest.raises(ConfigError, match=r"unknown key grid.'extra_m' .*; mind the unit"):
        check_keys(data, {"cell_m", "tau_s"}, "grid.", "mind the unit")
    with pytest.raises(ConfigError, match=r"missing key 'state'"):
        table(data, "state")
    assert table(data, "state", required=False) == {}
    with pytest.raises(ConfigError, match=r"key 'tau_s' must be a table"):
        table(data, "tau_s")
