"""`hil judge`: a recorded run held to the guarantee on a truth file, through the command line.

A short coarse run is recorded to a bag and its simulator's truth written to CSV in the
arena frame (the judge against the campaigns' is in tests/replay/test_truth.py); the
command passes it, and refuses a truth on another clock or a missing file with one line
and exit 2.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from hil.cli import main
from hil.runs.sim_run import SimRunSpec, simulate
from hil.runtime.settings import LoopConfig
from hil.sim.plant import TR_ETA

NS_PER_S = 1_000_000_000


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    """Return a short coarse run's bag, its arena truth CSV and a vessel config."""
    tmp = tmp_path_factory.mktemp("judge")
    spec = SimRunSpec(scenario="coarse", seed=2, cache_dir=tmp / "tables",
                      loop=LoopConfig(resynthesis_period_s=None, max_duration_s=8.0),
                      start=(0.0, -1.0, math.pi), out_dir=tmp / "run")
    truth = simulate(spec).sim.truth()
    path = tmp / "truth.csv"
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["t_ns", "x_m", "y_m", "psi_rad"])
        for t_s, x, y, psi in zip(truth[:, 0], *truth[:, 1 + TR_ETA : 1 + TR_ETA + 3].T,
                                  strict=True):
            writer.writerow([round(t_s * NS_PER_S), x, y, psi])
    config = tmp / "vessel.toml"
    config.write_text('scenario = "coarse"\n[loop]\nloop_hz = 20.0\n')
    return tmp / "run", path, config


def test_judge_passes_a_run_on_its_truth(
        recorded: tuple[Path, Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    log, truth, config = recorded
    status = main(["judge", str(log), "--truth", str(truth), "--config", str(config), "--json"])
    out, err = capsys.readouterr()
    assert status == 0, err
    verdict = json.loads(out.strip().splitlines()[-1])
    assert verdict["violations"] == 0
    assert verdict["intervals"] >= 2
    assert verdict["unjudged"] == []
    assert verdict["pose_offset_m"] < 0.01
    assert "verdict: PASS" in err


def test_judge_refuses_a_truth_on_another_clock(
        recorded: tuple[Path, Path, Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    log, truth, _ = recorded
    rows = np.genfromtxt(truth, delimiter=",", skip_header=1)
    moved = tmp_path / "epoch.csv"
    # The same states stamped on the epoch, as a wall-time recorder would: no decision
    # falls inside them.
    with moved.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["t_ns", "x_m", "y_m", "psi_rad"])
        for t_ns, x, y, psi in rows:
            writer.writerow([int(t_ns) + 1_700_000_000 * NS_PER_S, x, y, psi])
    assert main(["judge", str(log), "--truth", str(moved)]) == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith("hil judge: error: ")
    assert "not the same clock" in last


def test_judge_refuses_a_missing_truth_file(
        recorded: tuple[Path, Path, Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    log, _, _ = recorded
    assert main(["judge", str(log), "--truth", str(tmp_path / "none.csv")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "cannot read the true-state file" in err
