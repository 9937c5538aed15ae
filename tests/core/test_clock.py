import pytest

from hil.core.clock import SimClock, WallAnchor, WallClock


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


class _FakeWall:
    """A wall clock the test sets, and a sleep that moves it."""

    def __init__(self, now_ns: int) -> None:
        self.now_ns = now_ns
        self.slept_s: list[float] = []

    def __call__(self) -> int:
        return self.now_ns

    def sleep(self, seconds: float) -> None:
        self.slept_s.append(seconds)
        self.now_ns += round(seconds * 1e9)


def test_wall_anchor_paces_simulated_time_at_its_speed() -> None:
    wall = _FakeWall(5_000_000_000)
    anchor = WallAnchor(wall, t_ns=0, speed=2.0, slip_ns=20_000_000, sleep=wall.sleep)
    for k in range(1, 6):
        anchor.wait_for(k * 10_000_000)
    # 50 ms simulated at 2x take 25 ms of wall time, slept in 5 ms steps.
    assert wall.now_ns == 5_025_000_000
    assert wall.slept_s == pytest.approx([0.005] * 5)
    assert anchor.slips == 0
    assert anchor.wall_of(40_000_000) == 5_020_000_000


def test_wall_anchor_catches_up_a_small_lag_without_sleeping() -> None:
    wall = _FakeWall(0)
    anchor = WallAnchor(wall, t_ns=0, slip_ns=20_000_000, sleep=wall.sleep)
    assert anchor.wall_of(0) == 0
    wall.now_ns += 25_000_000  # 15 ms late for the period due at 10 ms
    anchor.wait_for(10_000_000)
    anchor.wait_for(20_000_000)
    assert wall.slept_s == []
    assert anchor.slips == 0
    assert anchor.wall_of(20_000_000) == 20_000_000  # stamps keep the first map


@pytest.mark.parametrize("jump_ns", [100_000_000, -1_000_000_000])
def test_wall_anchor_slips_when_the_wall_is_far_off(jump_ns: int) -> None:
    """A starved process or a clock set forward or back: stamps follow the wall at once."""
    wall = _FakeWall(1_000_000_000)
    anchor = WallAnchor(wall, t_ns=0, slip_ns=20_000_000, sleep=wall.sleep)
    anchor.wait_for(10_000_000)
    wall.now_ns += jump_ns
    anchor.wait_for(20_000_000)
    assert anchor.slips == 1
    assert anchor.slipped_ns == jump_ns - 10_000_000  # less the 10 ms it was early for
    assert wall.slept_s == pytest.approx([0.01])  # the slip itself sleeps nothing
    # The sample of simulated time 20 ms is stamped with the wall's present, not 100 ms old
    # (nor a second in the future).
    assert anchor.wall_of(20_000_000) == wall.now_ns
    anchor.wait_for(30_000_000)
    assert wall.now_ns == 1_010_000_000 + jump_ns + 10_000_000


def test_wall_anchor_refuses_a_speed_or_tolerance_that_is_not_positive() -> None:
    with pytest.raises(ValueError, match="speed"):
        WallAnchor(_FakeWall(0), t_ns=0, speed=0.0)
    with pytest.raises(ValueError, match="slip_ns"):
        WallAnchor(_FakeWall(0), t_ns=0, slip_ns=0)


def test_wall_anchor_anchors_on_first_use() -> None:
    """A slow first step (a compilation) between creation and first use is not a slip."""
    wall = _FakeWall(0)
    anchor = WallAnchor(wall, t_ns=0, slip_ns=20_000_000, sleep=wall.sleep)
    wall.now_ns = 7_000_000_000
    assert anchor.wall_of(0) == 7_000_000_000
    anchor.wait_for(10_000_000)
    assert anchor.slips == 0
    assert wall.now_ns == 7_010_000_000
