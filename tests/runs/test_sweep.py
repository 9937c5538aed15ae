import math
import tomllib
from pathlib import Path

import pytest

from hil.controllers.pid import PidGains
from hil.model.environment import EnvironmentalLoad
from hil.runs.sweep import SweepError, load_sweep, parse_sweep

GRID = """
max_duration_s = 30.0
scenarios = ["coarse"]
seeds = { first = 4, count = 2 }
starts = ["default", [0.25, -1.2, 120.0]]
start_velocities = ["rest", [0.05, 0.0, 10.0]]
[[gains]]
[[gains]]
kp_per_s = [6.0, 5.0, 10.0]
[[disturbances]]
gm_std_n = [0.5, 0.5, 0.05]
"""


def test_a_grid_is_every_combination_in_axis_order(tmp_path: Path) -> None:
    path = tmp_path / "grid.toml"
    path.write_text(GRID)
    points = load_sweep(path).points()
    assert len(points) == 1 * 2 * 2 * 2 * 2 * 1
    first, last = points[0].spec, points[-1].spec
    assert (first.scenario, first.seed, first.start, first.start_velocity) == (
        "coarse",
        4,
        None,
        None,
    )
    assert first.gains is None
    assert first.loop.max_duration_s == 30.0
    assert first.loop.resynthesis_period_s is None
    assert last.seed == 5
    assert last.start == pytest.approx((0.25, -1.2, math.radians(120.0)))
    assert last.start_velocity == pytest.approx((0.05, 0.0, math.radians(10.0)))
    assert last.gains == PidGains(kp_per_s=(6.0, 5.0, 10.0))
    # The disturbance's noise is seeded by the run's seed.
    assert last.load == EnvironmentalLoad(gm_std_n=(0.5, 0.5, 0.05), seed=5)
    assert points[-1].labels == {
        "scenario": "coarse",
        "seed": "5",
        "start": "[0.25, -1.2, 120.0]",
        "start_velocity": "[0.05, 0.0, 10.0]",
        "gains": "kp_per_s=[6.0, 5.0, 10.0]",
        "disturbance": "gm_std_n=[0.5, 0.5, 0.05]",
    }


def test_a_random_sample_draws_boxes_and_is_seeded() -> None:
    data = tomllib.loads("""
mode = "random"
samples = 20
seed = 7
scenarios = ["coarse", "paper"]
starts = [{ low = [0.0, -1.0, -90.0], high = [0.5, 1.0, 90.0] }]
""")
    points = parse_sweep(data).points()
    assert [p.spec for p in points] == [p.spec for p in parse_sweep(data).points()]
    assert len(points) == 20
    assert {p.spec.scenario for p in points} == {"coarse", "paper"}
    for p in points:
        assert p.spec.start is not None
        x, y, psi = p.spec.start
        assert 0.0 <= x <= 0.5
        assert -1.0 <= y <= 1.0
        assert abs(psi) <= math.pi / 2
    assert len({p.spec.start for p in points}) == 20


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        (
            "scenario = ['coarse']",
            "unknown sweep key\\(s\\) \\['scenario'\\]; allowed: .*scenarios",
        ),
        ("mode = 'lattice'", "key 'mode' must be 'grid' or 'random'"),
        ("mode = 'random'", "key 'samples' must be a whole number >= 1"),
        ("seeds = []", "key 'seeds' must be a non-empty list of integers"),
        ("seed = [0, 1]", "key 'seed' .* got \\[0, 1\\] \\(the runs' seeds are key 'seeds'\\)$"),
        (
            "max_duration_s = -1",
            "^key 'max_duration_s' must be a positive number of seconds, got -1$",
        ),
        ("starts = [[1.0, 2.0]]", "key 'starts': .*3 finite numbers"),
        ("starts = [{ low = [0, 0, 0], high = [1, 1, 1] }]", "needs mode = 'random'"),
        (
            "[[gains]]\nkp = [1, 2, 3]",
            r"^key 'gains': unknown field\(s\) \['kp'\] in .*; allowed \(PidGains\): .*kp_per_s",
        ),
        ("[[gains]]\nkd = 'x'", "^key 'gains': "),
        ("[[disturbances]]\ngm_std_n = [-1.0, 0.0, 0.0]", "gm_std_n must be non-negative"),
    ],
)
def test_a_bad_sweep_is_refused_naming_the_key(text: str, needle: str) -> None:
    with pytest.raises(SweepError, match=needle) as caught:
        parse_sweep(tomllib.loads(text))
    assert str(caught.value).count(" is no ") <= 1  # said once, not twice
