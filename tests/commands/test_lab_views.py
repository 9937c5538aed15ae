"""`hil inspect` and `hil plot` on a bag holding only the lab's topics."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest
from rerun.chunk import RrdReader

from hil.commands import inspect, plot
from tests.bag.bag_streams import tree_digest
from tests.replay.lab_bag import write_lab_bag

LOG = Path(__file__).resolve().parents[2] / "logs" / "coarse-high-seed2"


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("lab_views")
    return {
        "lab": write_lab_bag(LOG, root / "lab"),
        "no_pose": write_lab_bag(LOG, root / "no_pose", drop=["/voyager/measurement/pose"]),
        "nothing": write_lab_bag(
            LOG,
            root / "nothing",
            drop=["/voyager/measurement/pose", "/voyager/measurement/odom"],
        ),
    }


def _run(command: object, *argv: str) -> int:
    parser = argparse.ArgumentParser()
    command.add_arguments(parser)  # type: ignore[attr-defined]
    return command.run(parser.parse_args(list(argv)))  # type: ignore[attr-defined,no-any-return]


@pytest.mark.parametrize("scenario", [[], ["--scenario", "coarse"]], ids=["bare", "scenario"])
def test_inspect_writes_a_lab_bag(
    bags: dict[str, Path], tmp_path: Path, scenario: list[str],
    capsys: pytest.CaptureFixture[str],
) -> None:
    before = tree_digest(bags["lab"])
    out = tmp_path / "lab.rrd"
    assert _run(inspect, str(bags["lab"]), "-o", str(out), *scenario) == 0
    err = capsys.readouterr().err
    assert "a lab bag: no decisions recorded" in err
    assert ("pass --scenario" in err) == (not scenario)
    assert "/world/vessel" in RrdReader(out).store().schema().entity_paths()
    assert tree_digest(bags["lab"]) == before


def test_plot_draws_a_lab_bag_and_one_without_pose(
    bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for name in ("lab", "no_pose"):
        out = tmp_path / f"{name}.png"
        assert _run(plot, str(bags[name]), "-o", str(out), "--scenario", "coarse") == 0
        assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    capsys.readouterr()


@pytest.mark.parametrize("command", [inspect, plot], ids=["inspect", "plot"])
def test_a_lab_bag_with_nothing_to_draw_is_one_line(
    bags: dict[str, Path], tmp_path: Path, command: object,
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / ("x.rrd" if command is inspect else "x.png")
    assert _run(command, str(bags["nothing"]), "-o", str(out)) == 2
    err = capsys.readouterr().err
    assert "holds no pose and no state estimate" in err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
