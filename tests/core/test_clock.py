import pytest

from hil.core.clock import SimClock, WallAnchor, WallClock, read_beside


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
    """A steady and a system clock the test sets, and a sleep that moves both."""

    def __init__(self, steady_ns: int, system_minus_steady_ns: int = 0) -> None:
        self.steady_ns = steady_ns
        self.system_minus_steady_ns = system_minus_steady_ns
        self.slept_s: list[float] = []

    def steady(self) -> int:
        return self.steady_ns

    def system(self) -> int:
        return self.steady_ns + self.system_minus_steady_ns

    def sleep(self, seconds: float) -> None:
        self.slept_s.append(seconds)
        self.steady_ns += round(seconds * 1e9)

    def anchor(self, t_ns: int = 0, speed: float = 1.0) -> WallAnchor:
        return WallAnchor(t_ns, speed, slip_ns=500_000_000, steady=self.steady,
                          system=self.system, sleep=self.sleep)


def test_wall_anchor_paces_simulated_time_at_its_speed() -> None:
    wall = _FakeWall(5_000_000_000)
    anchor = wall.anchor(speed=2.0)
    for k in range(1, 6):
        anchor.wait_for(k * 10_000_000)
    # 50 ms simulated at 2x take 25 ms of wall time, slept in 5 ms steps.
    assert wall.steady_ns == 5_025_000_000
    assert wall.slept_s == pytest.approx([0.005] * 5)
    assert anchor.slips == 0


def test_wall_anchor_anchors_on_first_use() -> None:
    """A slow first step (a compilation) between creation and first use is not a slip."""
    wall = _FakeWall(0)
    anchor = wall.anchor()
    wall.steady_ns = 7_000_000_000
    assert anchor.system_of(0) == 7_000_000_000
    anchor.wait_for(10_000_000)
    assert anchor.slips == 0
    assert wall.steady_ns == 7_010_000_000


def test_wall_anchor_catches_up_a_lag_without_sleeping_or_slipping() -> None:
    """A busy CPU: the next periods run at once, and their stamps keep their due times."""
    wall = _FakeWall(0)
    anchor = wall.anchor()
    assert anchor.system_of(0) == 0
    wall.steady_ns += 310_000_000  # 300 ms late for the period due at 10 ms
    for k in range(1, 31):
        anchor.wait_for(k * 10_000_000)
    assert wall.slept_s == []
    assert anchor.slips == 0
    assert anchor.system_of(200_000_000) == 200_000_000


def test_wall_anchor_slips_when_far_behind() -> None:
    """A paused process: the stream goes on from the present, a gap, not a burst."""
    wall = _FakeWall(0)
    anchor = wall.anchor()
    anchor.wait_for(10_000_000)
    wall.steady_ns += 2_000_000_000
    anchor.wait_for(20_000_000)
    assert anchor.slips == 1
    assert anchor.slipped_ns == 2_000_000_000 - 10_000_000  # less the 10 ms it was early for
    assert anchor.system_of(20_000_000) == wall.steady_ns
    anchor.wait_for(30_000_000)
    assert wall.slept_s == pytest.approx([0.01, 0.01])


@pytest.mark.parametrize("step_ns", [100_000_000, -1_000_000_000])
def test_stamps_follow_a_step_of_the_system_clock_at_once(step_ns: int) -> None:
    """NTP or a resumed virtual machine sets the system clock: the pacing does not see it,
    the stamps move with it (else they would read as that much sensor latency)."""
    wall = _FakeWall(1_000_000_000, system_minus_steady_ns=1_700_000_000_000_000_000)
    anchor = wall.anchor()
    anchor.wait_for(10_000_000)
    wall.system_minus_steady_ns += step_ns
    anchor.wait_for(20_000_000)
    assert anchor.slips == 0
    assert wall.slept_s == pytest.approx([0.01, 0.01])
    assert anchor.system_of(20_000_000) == wall.system()


def test_wall_anchor_refuses_a_speed_or_tolerance_that_is_not_positive() -> None:
    with pytest.raises(ValueError, match="speed"):
        WallAnchor(0, speed=0.0)
    with pytest.raises(ValueError, match="slip_ns"):
        WallAnchor(0, slip_ns=0)


def test_read_beside_keeps_the_tightest_pair() -> None:
    """A read held between its steady reads is retried; the tightest pair is kept."""
    steady_reads = iter([0, 5_000_000, 5_000_010, 5_000_020])  # first pair held 5 ms
    clock_reads = iter([900, 5_000_915])
    reading, midpoint, span = read_beside(lambda: next(clock_reads), lambda: next(steady_reads))
    assert (reading, midpoint, span) == (5_000_915, 5_000_015, 10)
