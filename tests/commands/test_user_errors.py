"""Every error a user can cause ends in one line naming the value and exit 2, no traceback.

Each case of issue 12 (and its neighbours) is driven through the real command line.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from hil.cli import EXIT_BROKEN_PIPE, main

ROOT = Path(__file__).resolve().parents[2]
COARSE = (ROOT / "hil" / "scenarios" / "coarse.toml").read_text()


def _scenario(tmp_path: Path, old: str, new: str) -> str:
    assert old in COARSE
    path = tmp_path / "edited.toml"
    path.write_text(COARSE.replace(old, new))
    return str(path)


def _fails_with(argv: list[str], capsys: pytest.CaptureFixture[str], *needles: str) -> str:
    """Run `hil argv`; check exit 2, no traceback, and a last line naming `needles`."""
    try:
        status = main(argv)
    except SystemExit as exit_:  # argparse refuses the value
        status = exit_.code  # type: ignore[assignment]
    err = capsys.readouterr().err
    assert status == 2, err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    for needle in needles:
        assert needle in last, last
    return last


@pytest.mark.parametrize("value", ["0", "-5", "nan", "inf", "soon"])
def test_run_max_duration_must_be_positive(value: str, capsys: pytest.CaptureFixture[str]) -> None:
    _fails_with(["run", "coarse", "--max-duration", value], capsys, "--max-duration", repr(value))


def test_campaign_max_duration_must_be_positive(capsys: pytest.CaptureFixture[str]) -> None:
    _fails_with(["campaign", "coarse", "-n", "2", "--max-duration", "0"], capsys, "'0'")


@pytest.mark.parametrize(
    ("start", "needle"),
    [
        ("-1,2,0", "inside obstacle 'O2'"),  # no "=": a value that starts with "-"
        ("10,0,0", "outside the arena"),
        ("0.8,0,0", "hull corner past the arena's wall"),  # centre inside, bow 0.3 m past x = 1
        ("1,2", "'1,2'"),
        ("nan,0,0", "'nan,0,0'"),
    ],
)
def test_run_refuses_impossible_starts(
    start: str, needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    _fails_with(["run", "coarse", "--no-record", "--start", start], capsys, needle)


def test_scenario_with_the_retired_margin_says_what_replaced_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "old-margin.toml"
    path.write_text(COARSE.replace("[hull]", "[margin]\nnone = true\n\n[hull]"))
    _fails_with(["synth", str(path)], capsys, "'margin' was retired", "[transient]",
                "bench lowlevel")


def test_scenario_with_an_obstacle_outside_the_arena(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _scenario(tmp_path, 'x_m = [-1.25, -0.75]', 'x_m = [1.25, 1.75]')
    _fails_with(["run", path, "--no-record"], capsys, "'O2'", "outside the arena")


def test_vessel_config_with_a_bad_topic(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "vessel.toml"
    config.write_text('[ros.topics]\npose = "not a topic!"\n')
    _fails_with(["vessel", "--config", str(config)], capsys, "'not a topic!'")


def test_vessel_config_with_a_bad_domain(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "vessel.toml"
    config.write_text("[ros]\ndomain_id = 500\n")
    _fails_with(["vessel", "--config", str(config)], capsys, "domain_id", "500")


def test_vessel_check_refuses_bad_seconds_and_a_bad_config(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "vessel.toml"
    config.write_text("[ros]\ndomain_id = 500\n")
    _fails_with(["vessel", "--check", "--config", str(config)], capsys, "domain_id", "500")
    config.write_text("")
    _fails_with(["vessel", "--check", "--config", str(config), "--seconds", "0"], capsys,
                "--seconds")
    _fails_with(["vessel", "--config", str(config), "--seconds", "3"], capsys,
                "--seconds needs --check")


def test_sim_vessel_bad_domain_and_start(capsys: pytest.CaptureFixture[str]) -> None:
    _fails_with(["sim-vessel", "coarse", "--domain-id", "500"], capsys, "--domain-id", "500")
    _fails_with(["sim-vessel", "coarse", "--start", "10,0,0"], capsys, "outside the arena")


def test_bad_ros_domain_id_in_the_environment(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("rclpy")
    monkeypatch.setenv("ROS_DOMAIN_ID", "500")
    config = tmp_path / "vessel.toml"
    config.write_text(f'scenario = "coarse"\nruns_dir = "{tmp_path}"\n')
    _fails_with(["vessel", "--config", str(config)], capsys, "ROS_DOMAIN_ID", "'500'")


def test_viewers_without_a_display_say_so(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    if not sys.platform.startswith("linux"):
        pytest.skip("the display check is for Linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    log = str(ROOT / "logs" / "coarse-default-seed0")
    _fails_with(["inspect", log, "--spawn"], capsys, "no display", "-o run.rrd")
    _fails_with(["run", "coarse", "--no-record", "--rerun"], capsys, "no display", "--rerun")


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT)
    return env


def _address_space_limit_holds(limit: int) -> bool:
    """Whether a child process here really runs under an RLIMIT_AS it sets.

    qemu's user-mode emulation (the emulated Pi of ``pi_check.sh``) accepts the call but
    does not apply it (the limit would bind the emulator's own allocations), and its
    getrlimit then reports the host's unlimited value.
    """
    code = (
        "import resource; "
        f"resource.setrlimit(resource.RLIMIT_AS, ({limit}, {limit})); "
        "print(resource.getrlimit(resource.RLIMIT_AS)[0])"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    return out.stdout.strip() == str(limit)


def test_synth_on_a_grid_too_big_for_memory() -> None:
    # 450 x 500 x 120 cells, 175 layers: beyond the 4 GiB address space allowed below
    # (1-cm cells: the successor boxes still fit the kernel).
    huge = COARSE.replace("cell_m = [0.05, 0.05]", "cell_m = [0.01, 0.01]").replace(
        "heading_cells = 60", "heading_cells = 120"
    )
    assert huge != COARSE
    limit = 4 << 30
    if not _address_space_limit_holds(limit):
        pytest.skip("RLIMIT_AS is not applied here (qemu user-mode emulation ignores it)")

    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    proc = subprocess.run(
        [sys.executable, "-m", "hil", "synth", "/dev/stdin", "--no-cache", "--repeat", "1"],
        input=huge, capture_output=True, text=True, env=_env(),
        preexec_fn=cap, timeout=300, check=False,
    )
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr
    last = proc.stderr.strip().splitlines()[-1]
    assert "not enough memory" in last
    assert "cell_m" in last


def test_synth_on_a_grid_too_fine_for_the_budget() -> None:
    # 0.2-mm cells: a successor box spans hundreds of cells, which the kernel refuses.
    fine = COARSE.replace("cell_m = [0.05, 0.05]", "cell_m = [0.0002, 0.0002]")
    proc = subprocess.run(
        [sys.executable, "-m", "hil", "synth", "/dev/stdin", "--no-cache", "--repeat", "1"],
        input=fine, capture_output=True, text=True, env=_env(), timeout=300, check=False,
    )
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr
    last = proc.stderr.strip().splitlines()[-1]
    assert "too fine" in last
    assert "cell_m" in last


def test_info_into_a_closed_pipe_is_quiet() -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "hil", "info", str(ROOT / "logs" / "coarse-default-seed0")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=_env(),
    )
    assert proc.stdout is not None
    assert proc.stderr is not None
    proc.stdout.close()  # `| head` that has already gone
    err = proc.stderr.read().decode()
    proc.stderr.close()
    assert proc.wait(timeout=120) == EXIT_BROKEN_PIPE
    assert err == ""


def test_pytest_hil_logs_outside_the_repo_collects(tmp_path: Path) -> None:
    # pytest takes the option's value for a path and looks for its settings there (with
    # no test path given); the tests must import their helpers all the same.
    logs = tmp_path / "tank"
    logs.mkdir()
    # `hil` importable as an installed package is, the repository root not on the path.
    site = tmp_path / "site"
    site.mkdir()
    (site / "hil").symlink_to(ROOT / "hil")
    env = dict(os.environ)
    env["PYTHONPATH"] = str(site)
    proc = subprocess.run(
        [sys.executable, "-P", "-m", "pytest", "--hil-logs", str(logs), "--collect-only", "-q",
         "-p", "no:cacheprovider"],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=300, check=False,
    )
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert "tests collected" in proc.stdout


@pytest.mark.parametrize("command", ["run", "campaign", "sim-vessel"])
@pytest.mark.parametrize("value", ["-1", "two", "1.5"])
def test_a_seed_names_the_flag_and_what_it_allows(
    command: str, value: str, capsys: pytest.CaptureFixture[str]
) -> None:
    last = _fails_with([command, "--seed", value], capsys, "--seed", ">= 0", repr(value))
    assert last.startswith(f"hil {command}: error: argument --seed: ")


@pytest.mark.parametrize(
    ("text", "needles"),
    [
        ("seed = [0, 1]\n", ("key 'seed'", "[0, 1]", "key 'seeds'")),
        ("max_duration_s = 0\n", ("key 'max_duration_s'", "positive", "got 0")),
        ("[[gains]]\nkp = 1\n", ("key 'gains'", "['kp']", "allowed (PidGains)", "kp_per_s")),
        ("seedz = [1]\n", ("unknown sweep key(s) ['seedz']", "allowed:", "seeds")),
    ],
)
def test_a_sweep_typo_names_the_key_once(
    tmp_path: Path, text: str, needles: tuple[str, ...], capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "sweep.toml"
    path.write_text(text)
    last = _fails_with(["sweep", str(path)], capsys, *needles)
    assert last.startswith("hil sweep: error: ")
    assert last.count(" is no ") == 0


def test_synth_errors_name_the_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _scenario(tmp_path, "tau_s = 2.0", "tau_s = -2.0")
    last = _fails_with(["synth", path], capsys, "timing.'tau_s'")
    assert last.startswith("hil synth: error: ")


def test_ros_args_are_split_off_and_refused_where_they_mean_nothing(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from hil.cli import split_ros_args

    assert split_ros_args(["vessel", "--config", "c.toml", "--ros-args", "-r", "a:=b"]) == (
        ["vessel", "--config", "c.toml"], ("-r", "a:=b")
    )
    assert split_ros_args(["vessel", "--ros-args", "-p", "x:=1", "--", "--json"]) == (
        ["vessel", "--json"], ("-p", "x:=1")
    )
    assert split_ros_args(["synth", "coarse"]) == (["synth", "coarse"], ())
    assert main(["synth", "coarse", "--ros-args", "-r", "a:=b"]) == 2
    err = capsys.readouterr().err
    assert "hil synth: error: --ros-args is for vessel and sim-vessel only" in err
