"""`hil synth`: the report, the JSON line, the saved controller and the error exits."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from hil.cli import main
from hil.controllers.symbolic import Controller

COARSE = Path(__file__).parents[2] / "hil" / "scenarios" / "coarse.toml"


def test_synth_prints_a_report_and_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    saved = tmp_path / "ctrl.npz"
    status = main(
        [
            "synth",
            "coarse",
            "--json",
            "--save",
            str(saved),
            "--cache-dir",
            str(tmp_path),
            "--repeat",
            "1",
        ]
    )
    out = capsys.readouterr().out.strip().splitlines()
    assert status == 0
    summary = json.loads(out[-1])
    for key in (
        "synthesis_seconds",
        "abstraction_seconds",
        "iterations",
        "winning_fraction",
        "peak_memory_mb",
        "grid_cells",
    ):
        assert key in summary
    assert summary["grid"] == [90, 100, 60]
    assert summary["grid_cells"] == 90 * 100 * 60
    # From rest, of the cells the hull fits in: the corridor right of O2 is too narrow to
    # turn in, and the deviation budget costs a band along walls and the obstacle.
    assert 0.5 < summary["winning_fraction"] < 0.9
    # A first decision at rest (a campaign's start) may take any input into the winning
    # set, but budgeted for an unknown transient: a set of its own, reported beside.
    assert 0.3 < summary["first_decision_fraction"] < 0.9
    assert summary["first_decision_cells"] <= summary["free_cells"]
    assert summary["iterations"] > 10
    # 175 layers of winning bits, values and tubes on 540 000 cells.
    assert 0.0 < summary["peak_memory_mb"] < 600.0
    assert any(line.startswith("winning") for line in out[:-1])
    assert Controller.load(saved).stats.winning_cells == summary["winning_cells"]
    assert summary["controller_cached"] is False
    # Second run: tables and the solved controller come from the cache; a start is covered
    # before the full solve ends, at the level of its value, which is the full controller's.
    start = (-0.5, -1.2, 180.0)
    main(["synth", "coarse", "--json", "--cache-dir", str(tmp_path), "--repeat", "1",
          f"--start={start[0]},{start[1]},{start[2]}"])
    again = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert again["abstraction_cached"] is True
    assert again["controller_cached"] is True
    assert again["winning_cells"] == summary["winning_cells"]
    controller = Controller.load(saved)
    cell = controller.grid.cell_of((start[0], start[1], math.radians(start[2])))
    assert cell is not None
    assert again["start_cell"] == list(cell)
    assert again["start_value"] == controller.cell_value(cell) > 0
    assert again["start_levels"] == again["start_value"] < summary["iterations"]
    assert 0.0 < again["start_seconds"] < again["start_full_seconds"]
    # --no-cache reads and writes neither: both are built, nothing new on disk.
    before = sorted((p, p.stat().st_mtime_ns) for p in tmp_path.rglob("*"))
    main(["synth", "coarse", "--json", "--cache-dir", str(tmp_path), "--repeat", "1",
          "--no-cache"])
    fresh = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert fresh["abstraction_cached"] is False
    assert fresh["controller_cached"] is False
    assert fresh["winning_cells"] == summary["winning_cells"]
    assert sorted((p, p.stat().st_mtime_ns) for p in tmp_path.rglob("*")) == before


def test_synth_refuses_a_start_outside_the_grid(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["synth", "coarse", "--start=40,0,0"]) == 2
    assert "hil synth: error: --start 40,0,0 lies outside the grid" in capsys.readouterr().err


def test_synth_refuses_a_target_covered_by_an_inflated_obstacle(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = COARSE.read_text(encoding="utf-8")
    # A wall right of the target, inflated over all of it: no cell of it can be winning,
    # which the scenario check says before any synthesis (issue 12).
    text += (
        '\n[[obstacles]]\nname = "W"\nx_m = [-1.95, -1.9]\ny_m = [0.75, 2.25]\ninflation_m = 1.6\n'
    )
    path = tmp_path / "blocked.toml"
    path.write_text(text, encoding="utf-8")
    status = main(["synth", str(path), "--json", "--cache-dir", str(tmp_path), "--repeat", "1"])
    captured = capsys.readouterr()
    assert status == 2
    assert "'target' cannot be reached" in captured.err
    assert captured.out == ""


def test_synth_refuses_a_bad_scenario(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(
        COARSE.read_text(encoding="utf-8").replace("tau_s = 2.0", "tau_s = -2.0"), encoding="utf-8"
    )
    assert main(["synth", str(path)]) == 2
    assert "timing.'tau_s'" in capsys.readouterr().err


def _small(tmp_path: Path) -> str:
    """A coarse scenario on a 10-cm, 30-heading grid: a solve of well under a second."""
    text = COARSE.read_text(encoding="utf-8")
    small = text.replace("cell_m = [0.05, 0.05]", "cell_m = [0.1, 0.1]").replace(
        "heading_cells = 60", "heading_cells = 30"
    )
    assert small != text
    path = tmp_path / "small.toml"
    path.write_text(small, encoding="utf-8")
    return str(path)


def test_synth_solves_once_by_default_and_says_each_stage(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scenario = _small(tmp_path)
    main(["synth", scenario, "--json", "--cache-dir", str(tmp_path)])
    captured = capsys.readouterr()
    summary = json.loads(captured.out.strip().splitlines()[-1])
    assert summary["synthesis_runs"] == 1
    assert summary["repeat_seconds"] == []
    assert summary["repeat_median_seconds"] is None
    synthesis = [line for line in captured.out.splitlines() if line.startswith("synthesis")]
    assert len(synthesis) == 1
    assert "median" not in synthesis[0]
    assert f"{summary['synthesis_seconds']:.3f} s" in synthesis[0]
    # Each stage is said on stderr as it starts, then what it took; the total last.
    err = captured.err.splitlines()
    assert all(line.startswith("hil synth: ") for line in err)
    assert err[0] == f"hil synth: scenario {scenario}: loading (numpy, numba)"
    assert any(line.startswith("hil synth: loading the abstraction tables") for line in err)
    assert "hil synth: tables built in " in captured.err
    assert any(line.startswith("hil synth: synthesizing on ") for line in err)
    assert f"hil synth: solved in {summary['first_synthesis_seconds']:.2f} s" in captured.err
    assert err[-1].startswith("hil synth: done in ")
    # Again: tables from cache, the controller from the store, and the report says so.
    main(["synth", scenario, "--cache-dir", str(tmp_path)])
    again = capsys.readouterr()
    assert "hil synth: tables read from cache in " in again.err
    assert "hil synth: controller read from the solved-controller store in " in again.err
    assert "synthesis    read from the solved-controller store in " in again.out


def test_synth_repeat_solves_again_without_caches_and_adds_the_median(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    main(["synth", _small(tmp_path), "--json", "--cache-dir", str(tmp_path), "--repeat", "3"])
    captured = capsys.readouterr()
    summary = json.loads(captured.out.strip().splitlines()[-1])
    assert summary["synthesis_runs"] == 3
    assert len(summary["repeat_seconds"]) == 2
    assert summary["repeat_median_seconds"] == sorted(summary["repeat_seconds"])[0] + (
        sorted(summary["repeat_seconds"])[1] - sorted(summary["repeat_seconds"])[0]
    ) / 2
    assert "solved 2 more time(s) without caches: median" in captured.out
    assert captured.err.count("hil synth: solving again without caches") == 2


@pytest.mark.parametrize("value", ["0", "-2", "two"])
def test_synth_repeat_must_be_a_count(value: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["synth", "coarse", "--repeat", value])
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith("hil synth: error: argument --repeat: ")
    assert repr(value) in last
