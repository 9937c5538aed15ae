import threading

import pytest

from hil.core.samples import ObstacleLayout
from hil.core.shapes import Rect
from hil.runtime.resynthesis import ResynthesisMode, Resynthesizer


def _layout(t_ns: int) -> ObstacleLayout:
    return ObstacleLayout(t_ns, (Rect(0.0, 1.0, 0.0, 1.0),))


def test_inline_results_are_immediate_and_versioned() -> None:
    worker: Resynthesizer[int] = Resynthesizer(
        lambda layout, age: layout.t_ns * 2, ResynthesisMode.INLINE
    )
    assert worker.poll() is None
    worker.submit(_layout(3), 1.0)
    worker.submit(_layout(5), 1.0)
    result = worker.poll()
    assert result is not None
    assert (result.version, result.controller, result.error) == (2, 10, None)
    assert worker.poll() is None


def test_solver_failure_becomes_a_result_not_a_crash() -> None:
    def no_winning_set(layout: ObstacleLayout, report_age_s: float) -> int:
        raise ValueError("no winning cell at the start")

    worker: Resynthesizer[int] = Resynthesizer(no_winning_set, ResynthesisMode.INLINE)
    worker.submit(_layout(1), 1.0)
    result = worker.poll()
    assert result is not None
    assert result.controller is None
    assert result.error == "ValueError: no winning cell at the start"


def test_thread_mode_skips_superseded_layouts_and_never_blocks_submit() -> None:
    gate = threading.Event()
    started = threading.Event()
    solved: list[int] = []

    def slow_solve(layout: ObstacleLayout, report_age_s: float) -> int:
        started.set()
        gate.wait(5.0)
        solved.append(layout.t_ns)
        return layout.t_ns

    worker: Resynthesizer[int] = Resynthesizer(slow_solve, ResynthesisMode.THREAD)
    try:
        worker.submit(_layout(1), 1.0)
        assert started.wait(5.0)
        assert worker.busy
        for t in (2, 3, 4):  # submitted while layout 1 is being solved
            worker.submit(_layout(t), 1.0)
        assert worker.poll() is None
        gate.set()
        assert worker.wait_idle(timeout_s=5.0)
        result = worker.poll()
        assert result is not None
        assert result.controller == 4
        assert solved == [1, 4]
    finally:
        gate.set()
        worker.close()
    with pytest.raises(RuntimeError, match="closed"):
        worker.submit(_layout(9), 1.0)
