"""The one-page figure of a real short run, and `hil plot`."""

from __future__ import annotations

import argparse
import math
import struct
from pathlib import Path

import pytest

from hil.bag.run_data import load_run
from hil.commands import plot as plot_command
from hil.runs.sim_run import SimRunSpec, run_in_sim
from hil.runtime.settings import LoopConfig
from hil.views.controller_view import scenario_for
from hil.views.plot import (
    DEFAULT_DPI,
    FIGURE_SIZE_IN,
    run_figure,
    save_run_figure,
    tracking_rms_text,
)


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("plot") / "run"
    run_in_sim(
        SimRunSpec(
            scenario="coarse",
            seed=2,
            out_dir=out,
            loop=LoopConfig(resynthesis_period_s=None, max_duration_s=10.0),
        )
    )
    return out


def _png_size(path: Path) -> tuple[int, int]:
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", head[16:24])
    return width, height


def _plot(*argv: str) -> int:
    parser = argparse.ArgumentParser()
    plot_command.add_arguments(parser)
    return plot_command.run(parser.parse_args(list(argv)))


def test_figure_is_a_png_of_the_expected_size(bag: Path, tmp_path: Path) -> None:
    run = load_run(bag)
    scenario, _ = scenario_for(run)
    out = save_run_figure(run, scenario, tmp_path / "run.png", dpi=50)
    assert _png_size(out) == (round(FIGURE_SIZE_IN[0] * 50), round(FIGURE_SIZE_IN[1] * 50))


def test_hil_plot_writes_a_non_empty_png(
    bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run.png"
    assert _plot(str(bag), "-o", str(out)) == 0
    assert out.stat().st_size > 20_000  # a drawn page, not a blank one
    assert _png_size(out) == (
        round(FIGURE_SIZE_IN[0] * DEFAULT_DPI),
        round(FIGURE_SIZE_IN[1] * DEFAULT_DPI),
    )
    assert f"wrote {out}" in capsys.readouterr().out


def test_hil_plot_refuses_a_bad_log_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "not_a_bag.mcap"
    bad.write_bytes(b"hello, not an mcap file")
    assert _plot(str(bad), "-o", str(tmp_path / "x.png")) == 2
    err = capsys.readouterr().err
    assert err.startswith("hil plot: error: ")
    assert err.count("\n") == 1
    assert not (tmp_path / "x.png").exists()
    assert bad.read_bytes() == b"hello, not an mcap file"


def test_hil_plot_wants_a_png_name(
    bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _plot(str(bag), "-o", str(tmp_path / "run.jpg")) == 2
    assert "must end in .png" in capsys.readouterr().err


def test_velocity_panels_show_the_tracking_rms_replay_judges(bag: Path) -> None:
    run = load_run(bag)
    rms = run.tracking_error().rms()
    text = tracking_rms_text(run)
    assert text[0] == f"RMS error {rms[0]:.4f} m/s"
    assert text[2] == f"RMS error {math.degrees(rms[2]):.3f} deg/s"
    fig = run_figure(run, None)
    titles = [ax.get_title(loc="left") for ax in fig.axes]
    assert list(text) == [t for t in titles if t.startswith("RMS")]
