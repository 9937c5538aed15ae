"""`hil sweep` and `hil campaign` through the real command line: results file, resume, no Dask."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from hil.cli import main

SWEEP = """
max_duration_s = 60.0
scenarios = ["coarse"]
seeds = [0]
starts = ["default", [0.25, -1.2, 120.0]]
"""


def test_a_sweep_streams_its_runs_and_a_resume_reads_them_back(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(SWEEP)
    results = tmp_path / "results.jsonl"
    status = main(["sweep", str(sweep), "--workers", "1", "--results", str(results), "--json"])
    first = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert status == 0
    assert first["runs"] == 2
    assert first["docked"] == 2
    assert [r["start"] for r in first["per_run"]][1] == pytest.approx([0.25, -1.2, 2.0944],
                                                                       abs=1e-4)
    lines = results.read_text().splitlines()
    assert len(lines) == 3
    # Nothing left to run: the figures come back from the file, which stays as it was.
    status = main(["sweep", str(sweep), "--workers", "1", "--resume", str(results), "--json"])
    captured = capsys.readouterr()
    again = json.loads(captured.out.strip().splitlines()[-1])
    assert status == 0
    assert "2 run(s) read back from the results file" in captured.err
    assert again["per_run"] == first["per_run"]
    assert results.read_text().splitlines() == lines
    # The same file for another sweep is refused.
    sweep.write_text(SWEEP.replace("seeds = [0]", "seeds = [1]"))
    assert main(["sweep", str(sweep), "--workers", "1", "--resume", str(results)]) == 2
    assert "holds another 'sweep'" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [
    ["sweep", "SWEEP", "--dask"],
    ["campaign", "coarse", "-n", "2", "--scheduler", "tcp://127.0.0.1:1"],
])
def test_without_dask_the_dask_options_say_how_to_install_it(
        argv: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(SWEEP)
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    monkeypatch.delitem(sys.modules, "hil.runs.dask_executor", raising=False)
    status = main([str(sweep) if a == "SWEEP" else a for a in argv])
    err = capsys.readouterr().err
    assert status == 2
    assert "Traceback" not in err
    errors = [line for line in err.strip().splitlines() if ": error: " in line]
    assert len(errors) == 1  # one line of error, after the line saying what it starts
    assert "need Dask, which is not installed" in err
    assert "pip install -e '.[dask]'" in err
