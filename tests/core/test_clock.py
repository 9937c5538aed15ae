import pytest

from hil.core.clock import SimClock, WallClock


def test_sim_clock_advances_world_in_order_and_never_backwards() -> None:
    calls: list[tuple[int, int]] = []
    clock = SimClock(start_ns=5, advance=lambda a, b: calls.append((a, b)))
    clock.sleep_until(100)
    clock.sleep_until(50)  # in the past: ignored
    clock.sleep_until(250)
    assert clock.now_ns() == 250
    assert calls == [(5, 100), (100, 250)]


def test_wall_clock_sleeps_for_the_remaining_time_only() -> None:
    slept: list[float] = []
    clock = WallClock(sleep=slept.append)
    clock.sleep_until(clock.now_ns() + 50_000_000)
    clock.sleep_until(0)  # already passed: an overrun, no sleep
    assert len(slept) == 1
    assert 0.0 < slept[0] <= 0.05
    assert slept[0] == pytest.approx(0.05, abs=0.02)
