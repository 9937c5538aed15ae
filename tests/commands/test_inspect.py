"""`hil inspect`: a real run to .rrd, and bad or foreign logs get one clear line."""

from __future__ import annotations

import argparse
import hashlib
import shutil
from pathlib import Path

import pytest
from rerun.chunk import RrdReader

from hil.bag.reader import describe
from hil.commands import inspect
from hil.runs.sim_run import SimRunSpec, run_in_sim
from hil.runtime.settings import LoopConfig
from tests.bag.bag_streams import FOREIGN_BAGS

FOREIGN = FOREIGN_BAGS  # ../shared next to the repository root


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("inspect") / "run"
    run_in_sim(
        SimRunSpec(
            scenario="coarse",
            seed=4,
            out_dir=out,
            loop=LoopConfig(resynthesis_period_s=None, max_duration_s=8.0),
        )
    )
    return out


def _inspect(*argv: str) -> int:
    parser = argparse.ArgumentParser()
    inspect.add_arguments(parser)
    return inspect.run(parser.parse_args(list(argv)))


def _digest(path: Path) -> str:
    h = hashlib.sha256()
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for p in files:
        h.update(p.name.encode())
        h.update(p.read_bytes())
    return h.hexdigest()


def test_a_run_becomes_an_rrd_and_the_log_is_untouched(
    bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    before = _digest(bag)
    out = tmp_path / "run.rrd"
    assert _inspect(str(bag), "-o", str(out)) == 0
    assert _digest(bag) == before
    assert "/world/vessel" in RrdReader(out).store().schema().entity_paths()
    lines = capsys.readouterr().out.splitlines()
    # What it does, as it goes; the last line the true total (reading included).
    assert lines[0] == f"hil inspect: reading {bag} ..."
    assert any(
        line.startswith("hil inspect: re-synthesizing the winning set for ") for line in lines
    )
    assert f"hil inspect: writing {out} ..." in lines
    assert lines[-1].startswith(f"wrote {out} (")
    assert " s (writing " in lines[-1]


def test_default_output_is_the_log_name_in_the_current_directory(
    bag: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    assert _inspect(str(bag), "--no-winning-set") == 0
    assert (tmp_path / "run.rrd").stat().st_size > 0
    assert inspect.default_output(Path("x/y/run_0.mcap")) == Path("run_0.rrd")


def test_refuses_to_write_into_the_log(bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = _digest(bag)
    assert _inspect(str(bag), "-o", str(bag / "inside.rrd")) == 2
    assert "would write into the log" in capsys.readouterr().err
    assert _digest(bag) == before


def _made_bad_logs(bag: Path, root: Path) -> list[Path]:
    """Return damaged copies of a real run and a few non-logs."""
    missing_meta = root / "no_metadata"
    shutil.copytree(bag, missing_meta)
    (missing_meta / "metadata.yaml").unlink()
    missing_split = root / "missing_split"
    shutil.copytree(bag, missing_split)
    next(iter(sorted(missing_split.glob("*.mcap")))).unlink()
    text = root / "notes.mcap"
    text.write_text("not an mcap file\n")
    empty = root / "empty_dir"
    empty.mkdir()
    return [missing_meta, missing_split, text, empty, root / "does_not_exist"]


def _assert_one_line_error(code: int, err: str) -> None:
    assert code == 2
    assert err.startswith("hil inspect: error: "), err
    assert err.count("\n") == 1, err
    assert "Traceback" not in err


def test_bad_logs_get_one_line_and_status_2(
    bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for log in _made_bad_logs(bag, tmp_path / "bad"):
        before = _digest(log) if log.exists() else None
        code = _inspect(str(log), "-o", str(tmp_path / "out.rrd"))
        _assert_one_line_error(code, capsys.readouterr().err)
        assert (_digest(log) if log.exists() else None) == before
        assert not (tmp_path / "out.rrd").exists()


def test_a_truncated_run_is_shown_as_far_as_it_goes_or_refused_in_one_line(
    bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cut = tmp_path / "cut"
    shutil.copytree(bag, cut)
    last = sorted(cut.glob("*.mcap"))[-1]
    last.write_bytes(last.read_bytes()[: last.stat().st_size * 6 // 10])
    before = _digest(cut)
    info = describe(cut)
    assert any("ends early" in p for p in info.problems)
    code = _inspect(str(cut), "-o", str(tmp_path / "cut.rrd"))
    err = capsys.readouterr().err
    poses = sum(
        t.message_count for t in info.topics if t.name.endswith(("/pose", "/odom", "/estimate"))
    )
    if poses:  # complete chunks with poses survived: shown, with a note
        assert code == 0
        assert "ends early" in err
    else:  # no pose survived (the first split closed during the synthesis): refused
        _assert_one_line_error(code, err)
    assert _digest(cut) == before


@pytest.mark.skipif(not FOREIGN.is_dir(), reason="foreign bags not present")
@pytest.mark.parametrize(
    "name",
    sorted(p.name for p in FOREIGN.iterdir() if p.is_dir() or p.suffix == ".mcap")
    if FOREIGN.is_dir()
    else [],
)
def test_foreign_logs_get_one_line_and_status_2(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = FOREIGN / name
    before = _digest(log)
    code = _inspect(str(log), "-o", str(tmp_path / "out.rrd"))
    _assert_one_line_error(code, capsys.readouterr().err)
    assert _digest(log) == before


def test_an_output_in_a_missing_folder_gets_one_line(
    bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = _inspect(str(bag), "--no-winning-set", "-o", str(tmp_path / "missing" / "run.rrd"))
    err = capsys.readouterr().err
    _assert_one_line_error(code, err)
    assert "is not a folder" in err
