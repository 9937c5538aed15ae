"""A true trajectory from outside hil: file round trip, frames, resampling, and the judge.

The judge on a truth file is checked against the campaigns' judge on the same simulated
run: a coarse run recorded to a bag, its simulator's truth written out in the lab's NED
world with the clock shifted to the epoch (as a wall-time run on the tank would stamp
it), judged by :func:`judge_log_on_truth`, must give what :func:`judge_outcome` gives.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from hil.adapters.frames import ArenaTransform
from hil.bag.run_data import load_run
from hil.core.samples import Frame
from hil.replay.truth import TrueTrajectory, TruthError, judge_log_on_truth, load_truth
from hil.runs.guarantee import judge_outcome
from hil.runs.sim_run import SimRunSpec, simulate
from hil.runtime.settings import LoopConfig
from hil.sim.plant import TR_ETA

NS_PER_S = 1_000_000_000
# Arena origin 2 m north and 1 m west of the lab's, its x axis east: arena (x, y, psi)
# is lab (north 2 - y, east -1 + x, yaw psi + pi/2).
TRANSFORM = ArenaTransform(origin_north_m=2.0, origin_east_m=-1.0, yaw_rad=math.pi / 2)
HEADER = ["t_ns", "north_m", "east_m", "yaw_rad", "u_mps", "v_mps", "r_radps"]


def _write(path: Path, header: list[str], rows: list[list[object]]) -> Path:
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(header)
        writer.writerows(rows)
    return path


def _lab_rows(t_ns: np.ndarray, eta: np.ndarray) -> list[list[object]]:
    """Arena poses (N, 3) as lab rows, by the closed form of TRANSFORM."""
    return [[int(t), 2.0 - y, -1.0 + x, math.remainder(psi + math.pi / 2, 2 * math.pi), 0, 0, 0]
            for t, (x, y, psi) in zip(t_ns, eta, strict=True)]


def test_a_lab_truth_file_reads_back_and_maps_to_the_arena(tmp_path: Path) -> None:
    arena = np.array([[0.25, -1.2, math.radians(120.0)], [0.3, -1.1, math.radians(-170.0)]])
    path = _write(tmp_path / "truth.csv", HEADER, _lab_rows(np.array([5, 15]), arena))
    truth = load_truth(path)
    assert truth.frame is Frame.LAB_NED
    assert truth.t_ns.tolist() == [5, 15]
    np.testing.assert_allclose(truth.eta[0], [3.2, -0.75, math.radians(-150.0)], atol=1e-12)
    mapped = truth.to_arena(TRANSFORM)
    assert mapped.frame is Frame.ARENA
    np.testing.assert_allclose(mapped.eta, arena, atol=1e-12)
    assert mapped.to_arena(TRANSFORM) is mapped


def test_an_arena_truth_file_needs_no_transform(tmp_path: Path) -> None:
    path = _write(tmp_path / "truth.csv", ["t_ns", "x_m", "y_m", "psi_rad"],
                  [[0, 1.0, 2.0, 0.5], [10, 1.1, 2.0, 0.5]])
    truth = load_truth(path)
    assert truth.frame is Frame.ARENA
    np.testing.assert_allclose(truth.to_arena(TRANSFORM).eta[1], [1.1, 2.0, 0.5])


def test_resampling_is_uniform_and_interpolates_the_heading_across_the_wrap() -> None:
    truth = TrueTrajectory(np.array([1_000 * NS_PER_S, 1_000 * NS_PER_S + 40_000_000]),
                           np.array([[0.0, 0.0, math.pi - 0.1], [0.4, -0.4, -math.pi + 0.1]]),
                           Frame.ARENA)
    t_s, eta = truth.resampled(0.01)
    np.testing.assert_allclose(np.diff(t_s), 0.01, atol=1e-6)
    assert t_s[0] == pytest.approx(1_000.0)
    assert len(eta) == 5
    np.testing.assert_allclose(eta[2, :2], [0.2, -0.2])
    # Halfway between pi - 0.1 and -pi + 0.1 the short way is pi, not 0.
    assert abs(math.remainder(eta[2, 2] - math.pi, 2 * math.pi)) < 1e-9


@pytest.mark.parametrize(("header", "rows", "match"), [
    (["t", "north_m", "east_m", "yaw_rad"], [[0, 0, 0, 0], [1, 0, 0, 0]], "names neither"),
    (HEADER[:4], [[0, 0, 0, 0]], "at least 2"),
    (HEADER[:4], [[0, 0, 0, 0], [0, 0, 0, 0]], "increase strictly"),
    (HEADER[:4], [[0, 0, 0, 0], [1, "nan", 0, 0]], "non-finite"),
    (HEADER[:4], [[0, 0, 0, 0], [1.5, 0, 0, 0]], "line 3"),
])
def test_bad_truth_files_are_refused_naming_what_is_wrong(
        tmp_path: Path, header: list[str], rows: list[list[object]], match: str) -> None:
    with pytest.raises(TruthError, match=match):
        load_truth(_write(tmp_path / "truth.csv", header, rows))


def test_a_missing_truth_file_is_refused(tmp_path: Path) -> None:
    with pytest.raises(TruthError, match="cannot read"):
        load_truth(tmp_path / "nowhere.csv")


def test_the_judge_on_a_truth_file_agrees_with_the_campaign_judge(tmp_path: Path) -> None:
    # A winning moving start of the coarse scenario, recorded to a bag.
    spec = SimRunSpec(scenario="coarse", seed=1, cache_dir=tmp_path / "tables",
                      loop=LoopConfig(resynthesis_period_s=None, max_duration_s=120.0),
                      start=(0.25, -1.2, math.radians(120.0)), start_velocity=(0.1, -0.05, 0.1),
                      out_dir=tmp_path / "run")
    outcome = simulate(spec)
    assert outcome.summary.docked
    truth = outcome.sim.truth()
    t_ns = np.round(truth[:, 0] * NS_PER_S).astype(np.int64)
    eta = truth[:, 1 + TR_ETA : 1 + TR_ETA + 3]
    path = _write(tmp_path / "truth.csv", HEADER, _lab_rows(t_ns, eta))
    judged = judge_log_on_truth(spec.out_dir or tmp_path, load_truth(path), TRANSFORM)
    # The campaigns' judge: the simulator's own truth and controllers, the same decisions.
    expected = judge_outcome(spec, outcome, load_run(spec.out_dir or tmp_path).decisions)
    assert judged.unjudged == ()
    assert judged.violations == expected
    assert judged.violations.intervals >= 10
    # The poses the stack received are the truth plus 1-mm, 0.1-deg sensor noise.
    assert judged.pose_offset_m < 0.01
    assert judged.heading_offset_rad < math.radians(1.0)
