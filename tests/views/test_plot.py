"""The one-page figure of a real short run, and `hil plot`."""

from __future__ import annotations

import argparse
import math
import struct
from pathlib import Path

import numpy as np
import pytest

from hil.bag.run_data import load_run
from hil.commands import plot as plot_command
from hil.runs.sim_run import SimRunSpec, run_in_sim
from hil.runtime.settings import LoopConfig
from hil.views.controller_view import scenario_for
from hil.views.plot import (
    ARENA_TITLE,
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
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"hil plot: reading {bag} ..."
    assert f"hil plot: drawing {out} ..." in lines
    assert lines[-1].startswith(f"wrote {out} in ")


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


def _signed_area(points: np.ndarray) -> float:
    """Return the shoelace area of a polyline closed on itself; < 0 is clockwise (y up)."""
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


# North, then a quarter turn to starboard (heading grows), then east: r > 0.
STARBOARD_ARC = np.array(
    [[math.sin(a), 1.0 - math.cos(a)] for a in np.linspace(0.0, math.pi / 2, 9)]
)


def test_the_arena_is_drawn_as_seen_from_above(bag: Path) -> None:
    run = load_run(bag)
    scenario, _ = scenario_for(run)
    assert scenario is not None
    fig = run_figure(run, scenario)
    arena = fig.axes[0]
    # The trajectory is plotted in arena data coordinates (x, y), not swapped ...
    path = next(line for line in arena.get_lines() if line.get_label() == "trajectory (estimate)")
    np.testing.assert_array_equal(path.get_xydata(), run.estimate.values[:, :2])
    # ... and on the page a starboard turn comes out clockwise (display y points up).
    on_page = arena.transData.transform(STARBOARD_ARC)
    assert _signed_area(on_page) < 0, "a starboard turn must be drawn clockwise (from above)"
    assert arena.yaxis_inverted()
    assert not arena.xaxis_inverted()
    assert "north" in arena.get_xlabel()
    assert "east" in arena.get_ylabel()
    assert arena.get_title() == ARENA_TITLE
    texts = {t.get_text() for t in arena.texts}
    assert {"start", "end", "T1"} <= texts
    assert {o.name for o in scenario.obstacles} <= texts


def test_a_scenario_less_figure_is_also_seen_from_above(bag: Path) -> None:
    fig = run_figure(load_run(bag), None)
    on_page = fig.axes[0].transData.transform(STARBOARD_ARC)
    assert _signed_area(on_page) < 0
    assert "O1" in {t.get_text() for t in fig.axes[0].texts}
