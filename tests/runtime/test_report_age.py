"""The report age a controller is solved for: the scenario's, or what the runtime measured.

Unit rules of :class:`ReportAgeBudget`, the simulated latency of a slower solver
(:class:`Resynthesizer` inline with ``latency_s``), and the scenario key that selects the
measured age.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hil import scenarios
from hil.core.samples import ObstacleLayout
from hil.core.shapes import Rect
from hil.runtime.report_age import MARGIN, QUANTUM_S, WINDOW, ReportAgeBudget
from hil.runtime.resynthesis import ResynthesisMode, Resynthesizer
from hil.runtime.settings import NS_PER_S
from hil.scenarios import ScenarioError, load_scenario
from hil.scenarios.scenario import Scenario


def _ns(t_s: float) -> int:
    return round(t_s * NS_PER_S)


def test_stated_ages_ignore_every_measurement() -> None:
    budget = ReportAgeBudget(1.0, tracks=True, measured=False)
    budget.in_force(0, _ns(5.0))
    budget.superseded(0, _ns(9.0))
    assert budget.next_s() == 1.0
    assert budget.largest_age_s == 9.0  # still measured, for the summary


def test_fixed_obstacles_are_never_measured() -> None:
    budget = ReportAgeBudget(2.0, tracks=False, measured=True)
    assert not budget.measured
    budget.in_force(0, _ns(5.0))
    assert budget.next_s() == 2.0


def test_measured_age_is_the_stated_one_until_a_controller_went_in_force() -> None:
    budget = ReportAgeBudget(1.0, measured=True)
    budget.reported(0)
    budget.reported(_ns(0.5))
    assert budget.next_s() == 1.0


def test_measured_age_covers_latency_plus_the_next_report_with_margin() -> None:
    budget = ReportAgeBudget(1.0, measured=True)
    for k in range(4):
        budget.reported(_ns(0.5 * k))  # reports every 0.5 s
    budget.in_force(0, _ns(1.5))  # latency 1.5 s: slower than the reports
    # Relied on up to L + max(I, L) = 3.0 s: 1.25 x 3.0 = 3.75 s, a multiple of 0.25 s.
    assert budget.next_s() == pytest.approx(MARGIN * 3.0)
    budget.superseded(0, _ns(3.6))  # measured older than predicted: it wins
    assert budget.next_s() == pytest.approx(4.5)  # 1.25 x 3.6 = 4.5


def test_a_fast_solver_gets_a_small_age_rounded_up_to_the_quantum() -> None:
    budget = ReportAgeBudget(1.0, measured=True)
    budget.reported(0)
    budget.reported(_ns(0.5))
    budget.in_force(_ns(0.5), _ns(0.55))  # 50 ms: one loop tick
    # 1.25 x (0.05 + 0.5) = 0.6875 -> 0.75 s: less growth than the stated 1 s.
    assert budget.next_s() == 0.75
    assert budget.next_s() % QUANTUM_S == 0.0


def test_a_slow_spell_is_forgotten_after_the_window() -> None:
    budget = ReportAgeBudget(1.0, measured=True)
    budget.in_force(0, _ns(4.0))  # one slow solve
    assert budget.next_s() == pytest.approx(10.0)  # 1.25 x (4 + 4)
    for k in range(WINDOW):
        t = _ns(10.0 + k)
        budget.in_force(t, t + _ns(0.2))
    assert budget.next_s() == pytest.approx(0.5)  # 1.25 x (0.2 + 0.2) = 0.5


def test_a_stated_age_must_be_positive() -> None:
    with pytest.raises(ValueError, match="> 0"):
        ReportAgeBudget(0.0)


class _Clock:
    def __init__(self) -> None:
        self.t_ns = 0

    def now_ns(self) -> int:
        return self.t_ns


def _layout(t_s: float, y: float = 0.0) -> ObstacleLayout:
    return ObstacleLayout(_ns(t_s), (Rect(0.0, 1.0, y, y + 1.0),))


def test_a_simulated_latency_hands_results_out_late_one_solve_at_a_time() -> None:
    clock = _Clock()
    solved: list[tuple[int, float]] = []

    def solve(layout: ObstacleLayout, age: float) -> int:
        solved.append((layout.t_ns, age))
        return layout.t_ns

    worker: Resynthesizer[int] = Resynthesizer(
        solve, ResynthesisMode.INLINE, latency_s=1.0, clock=clock.now_ns
    )
    worker.submit(_layout(0.0), 2.0)
    assert worker.busy
    clock.t_ns = _ns(0.5)
    worker.submit(_layout(0.5, 0.1), 2.0)  # the worker is busy: waits
    worker.submit(_layout(0.6, 0.2), 2.0)  # supersedes the waiting one
    assert worker.poll() is None
    clock.t_ns = _ns(1.0)
    first = worker.poll()
    assert first is not None
    assert (first.controller, first.report_age_s, first.seconds) == (0, 2.0, 1.0)
    clock.t_ns = _ns(1.9)
    assert worker.poll() is None  # started at 1.0 s, when the first was done
    clock.t_ns = _ns(2.0)
    second = worker.poll()
    assert second is not None
    assert second.controller == _ns(0.6)
    assert [t for t, _ in solved] == [0, _ns(0.6)]  # the superseded one never ran
    # The same shapes and age again: as from the solver's memo, at once.
    worker.submit(_layout(2.0, 0.2), 2.0)
    again = worker.poll()
    assert again is not None
    assert again.seconds == 0.0
    assert not worker.busy


def test_a_latency_needs_an_inline_solver_and_a_clock() -> None:
    with pytest.raises(ValueError, match="inline only"):
        Resynthesizer(lambda layout, age: 0, ResynthesisMode.INLINE, latency_s=1.0)
    with pytest.raises(ValueError, match=">= 0"):
        Resynthesizer(lambda layout, age: 0, ResynthesisMode.INLINE, latency_s=-1.0)


def _coarse_with(tmp_path: Path, obstacle_motion: str) -> Scenario:
    source = Path(scenarios.__file__).parent / "coarse.toml"
    edited = source.read_text().replace(
        "position_tolerance_m = 0.01", f"position_tolerance_m = 0.01\n{obstacle_motion}", 1
    )
    path = tmp_path / "coarse-edited.toml"
    path.write_text(edited)
    return load_scenario(str(path))


def test_the_scenario_selects_the_measured_age_and_keeps_old_hashes(tmp_path: Path) -> None:
    coarse = load_scenario("coarse")
    assert coarse.tracking.report_age == "stated"
    # As written before the key existed: the scenario's hash, which its logs carry, is kept.
    assert repr(coarse.tracking) == (
        "ObstacleTracking(max_report_age_s=1.0, position_tolerance_m=0.01)"
    )
    measured = _coarse_with(tmp_path, 'report_age = "measured"')
    assert measured.tracking.measures_report_age
    assert measured.digest() != coarse.digest()
    with pytest.raises(ScenarioError, match=r"report_age.*'stated', 'measured'.*'fast'"):
        _coarse_with(tmp_path, 'report_age = "fast"')
