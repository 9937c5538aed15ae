"""The QTM frame's path to a pose: rotation matrix to heading, mm to m, the arena
transform, the clock mapping, drops, losses and stalls (no network)."""

from __future__ import annotations

import math

import pytest

from hil.adapters.frames import ArenaTransform
from hil.adapters.qtm_feed import (
    ClockMapping,
    ClockSettings,
    QtmError,
    QtmFeed,
    body_index,
    body_names,
    lab_pose_from_6d,
    yaw_from_rotation_matrix,
)
from hil.core.clock import NS_PER_S
from hil.core.samples import Frame
from tests.adapters.qtm_server import parameters_xml, rotation_matrix

IDENTITY = rotation_matrix(0.0)
MS = 1_000_000  # ns per ms


@pytest.mark.parametrize("yaw", [0.0, 0.3, -1.2, math.pi / 2, 3.0, -3.0, -math.pi])
@pytest.mark.parametrize(("pitch", "roll"), [(0.0, 0.0), (0.2, -0.3), (-0.4, 0.5)])
def test_heading_of_a_rotation_matrix_is_its_yaw_under_any_tilt(
        yaw: float, pitch: float, roll: float) -> None:
    got = yaw_from_rotation_matrix(rotation_matrix(yaw, pitch, roll))
    assert math.remainder(got - yaw, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
    assert -math.pi <= got < math.pi


def test_the_matrix_is_read_column_by_column() -> None:
    # R = Rz(0.5): column-major (c, s, 0, -s, c, 0, 0, 0, 1); read row-major it would be -0.5.
    c, s = math.cos(0.5), math.sin(0.5)
    assert yaw_from_rotation_matrix((c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0)) == pytest.approx(0.5)


def test_a_lost_or_vertical_body_has_no_heading() -> None:
    assert math.isnan(yaw_from_rotation_matrix([math.nan] * 9))
    assert math.isnan(yaw_from_rotation_matrix(rotation_matrix(0.3, pitch_rad=1.4)))


def test_lab_pose_is_metres_and_radians_in_the_lab_frame() -> None:
    pose = lab_pose_from_6d(7, (1234.5, -250.0, -120.0), rotation_matrix(0.7))
    assert pose is not None
    assert (pose.t_ns, pose.frame) == (7, Frame.LAB_NED)
    assert (pose.x_m, pose.y_m, pose.yaw_rad) == pytest.approx((1.2345, -0.25, 0.7), abs=1e-12)
    assert lab_pose_from_6d(7, (math.nan, 0.0, 0.0), IDENTITY) is None
    assert lab_pose_from_6d(7, (0.0, 0.0, 0.0), [math.nan] * 9) is None


def test_feed_maps_through_the_arena_transform() -> None:
    # Arena origin at lab (1, -2), its x axis 0.3 rad from north; the body 2 m along the
    # arena's x axis, heading 0.4 rad in the lab: arena (2, 0), heading 0.1 rad.
    transform = ArenaTransform(origin_north_m=1.0, origin_east_m=-2.0, yaw_rad=0.3)
    feed = QtmFeed("2", transform)
    north, east = 1.0 + 2.0 * math.cos(0.3), -2.0 + 2.0 * math.sin(0.3)
    pose = feed.frame(5 * MS, 1000, 1, (north * 1e3, east * 1e3, 0.0), rotation_matrix(0.4))
    assert pose is not None
    assert pose.frame is Frame.ARENA
    assert (pose.x_m, pose.y_m, pose.yaw_rad) == pytest.approx((2.0, 0.0, 0.1), abs=1e-12)
    # The body offset comes from the same transform as the ROS backend's.
    offset = ArenaTransform(body_offset_x_m=0.1)
    pose = QtmFeed("2", offset).frame(5 * MS, 1000, 1, (0.0, 0.0, 0.0), rotation_matrix(math.pi))
    assert pose is not None
    assert (pose.x_m, pose.y_m) == pytest.approx((-0.1, 0.0), abs=1e-12)


def test_body_is_found_by_name_in_index_order() -> None:
    xml = parameters_xml(["1", "hull", "2"])
    assert body_names(xml) == ["1", "hull", "2"]
    assert body_index(xml.encode(), "2") == 2
    with pytest.raises(QtmError, match=r"no 6D rigid body 'tug'.*\['1', 'hull', '2'\]"):
        body_index(xml, "tug")
    with pytest.raises(QtmError, match="not XML"):
        body_names(b"<QTM_Parameters_Ver_1.25><The_6D>")
    with pytest.raises(QtmError, match="no The_6D section"):
        body_names("<QTM_Parameters_Ver_1.25><The_3D/></QTM_Parameters_Ver_1.25>")


def test_offset_is_the_smallest_delay_in_the_window() -> None:
    clock = ClockMapping(ClockSettings(window=3, settle=0))
    qtm = [k * 10 * MS for k in range(6)]
    delays = [5 * MS, 3 * MS, 4 * MS, 6 * MS, 7 * MS, 8 * MS]
    stamps = [clock.map(q + 100 * MS + d, q) for q, d in zip(qtm, delays, strict=True)]
    offsets = [s - q for (s, _), q in zip(stamps, qtm, strict=True)]
    # min over the last three delays: 5, 3, 3, 3, 4, 6 (plus the clocks' 100 ms apart)
    assert offsets == [105 * MS, 103 * MS, 103 * MS, 103 * MS, 104 * MS, 106 * MS]
    assert all(why == "" for _, why in stamps)
    assert all(s <= q + 100 * MS + d for (s, _), q, d in zip(stamps, qtm, delays, strict=True))


def test_a_leap_of_qtm_time_is_a_jump_and_a_new_estimate() -> None:
    clock = ClockMapping(ClockSettings(window=50, jump_tolerance_s=0.02, settle=5))
    for k in range(10):
        t, why = clock.map(k * 10 * MS + 2 * MS, k * 10 * MS)
        assert why == ""
    assert clock.offset_ns == 2 * MS
    # QTM's clock leaps 0.5 s ahead: the stamp follows QTM's new time with a new offset.
    t, why = clock.map(100 * MS + 2 * MS, 600 * MS)
    assert why == "QTM time leapt ahead by 0.500 s"
    assert clock.offset_ns == -498 * MS
    assert t == 102 * MS
    # ... a leap within the tolerance is absorbed silently.
    for k in range(11, 20):
        _, why = clock.map(k * 10 * MS + 2 * MS, k * 10 * MS + 510 * MS)
        assert why == ""
    assert clock.offset_ns == -508 * MS


def test_qtm_time_running_back_is_a_jump() -> None:
    clock = ClockMapping(ClockSettings(settle=2))
    for k in range(5):
        clock.map(k * 10 * MS + MS, k * 10 * MS)
    t, why = clock.map(50 * MS + MS, 10 * MS)
    assert why == "QTM time ran back by 0.030 s"
    assert t == 51 * MS
    assert clock.offset_ns == 41 * MS


def test_a_first_late_frame_settles_without_a_jump() -> None:
    clock = ClockMapping(ClockSettings(settle=3))
    _, why0 = clock.map(80 * MS, 0)  # 80 ms late: the connection's first frame
    _, why1 = clock.map(10 * MS + MS, 10 * MS)
    assert (why0, why1) == ("", "")
    assert clock.offset_ns == MS


def test_window_ageing_out_a_faster_path_re_estimates() -> None:
    clock = ClockMapping(ClockSettings(window=5, jump_tolerance_s=0.01, settle=0))
    for k in range(5):
        clock.map(k * 10 * MS + MS, k * 10 * MS)
    whys = [clock.map(k * 10 * MS + 50 * MS, k * 10 * MS)[1] for k in range(5, 10)]
    assert whys[:4] == ["", "", "", ""]
    assert whys[4] == "the offset rose by 0.049 s over 5 frames"


@pytest.mark.parametrize("step_ms", [100, -250])
def test_a_step_of_the_run_clock_moves_the_offset_at_once(step_ms: int) -> None:
    """NTP sets the vessel computer's clock: the stamps stay true to the arrivals' clock."""
    clock = ClockMapping(ClockSettings(window=200, jump_tolerance_s=0.02, settle=5))
    latency = 3 * MS
    set_by = 0
    for k in range(60):
        if k == 30:
            set_by = step_ms * MS
        steady = 5_000 * MS + k * 10 * MS + latency
        t, why = clock.map(steady + set_by, k * 10 * MS, steady_ns=steady)
        # Every frame as fast as the fastest: stamped at its arrival, on the run clock as it
        # reads now (not the step behind or ahead).
        assert t == steady + set_by
        expected = (f"the run's clock was set by {step_ms / 1000:+.3f} s (the offset moved "
                    "with it)") if k == 30 else ""
        assert why == expected


def test_without_a_steady_clock_a_run_clock_step_ages_out_of_the_window() -> None:
    """What the steady clock saves: the offset keeps the old minimum for a whole window."""
    clock = ClockMapping(ClockSettings(window=20, jump_tolerance_s=0.02, settle=5))
    stamps = [clock.map(k * 10 * MS + 3 * MS + (100 * MS if k >= 30 else 0), k * 10 * MS)[0]
              for k in range(60)]
    assert stamps[30] == 30 * 10 * MS + 3 * MS  # 100 ms before the frame's arrival
    assert stamps[48] == 48 * 10 * MS + 3 * MS  # and so until the window aged out
    assert stamps[59] == 59 * 10 * MS + 103 * MS


def test_a_late_arrival_read_is_no_clock_step() -> None:
    """A held thread delays both reads alike: only the pair's difference counts."""
    clock = ClockMapping(ClockSettings(settle=2))
    for k in range(10):
        late = 40 * MS if k == 5 else 0
        steady = k * 10 * MS + MS + late
        _, why = clock.map(steady + 7 * MS, k * 10 * MS, steady_ns=steady)
        assert why == ""


def test_frame_number_gaps_are_drops() -> None:
    feed = QtmFeed("2", ArenaTransform())
    for n in (1, 2, 3, 6, 7, 9):
        feed.frame(n * 10 * MS, n * 10_000, n, (0.0, 0.0, 0.0), IDENTITY)
    assert feed.counts.drops == 3
    assert feed.counts.frames == feed.counts.poses == 6
    assert [(e.code, e.text) for e in feed.events] == [
        ("qtm_drop", "qtm: 2 frame(s) dropped (4..5)"),
        ("qtm_drop", "qtm: 1 frame(s) dropped (8)"),
    ]
    feed.frame(100 * MS, 100_000, 1, (0.0, 0.0, 0.0), IDENTITY)
    assert feed.events[-1].code == "qtm_frames_restarted"
    assert feed.counts.drops == 3
    # A new connection is a new stream: no drops across it.
    feed.restart()
    feed.frame(200 * MS, 200_000, 50, (0.0, 0.0, 0.0), IDENTITY)
    assert feed.counts.drops == 3


def test_a_lost_body_gives_no_pose_and_two_events() -> None:
    feed = QtmFeed("hull", ArenaTransform())
    nan = (math.nan, math.nan, math.nan)
    got = [feed.frame(n * 10 * MS, n * 10_000, n, nan if 3 <= n < 6 else (1.0, 2.0, 0.0),
                      [math.nan] * 9 if 3 <= n < 6 else IDENTITY) for n in range(1, 9)]
    assert [g is None for g in got] == [False, False, True, True, True, False, False, False]
    assert (feed.counts.lost, feed.counts.poses) == (3, 5)
    assert [(e.code, e.text) for e in feed.events] == [
        ("qtm_body_lost", "qtm: body 'hull' lost at frame 3 (no pose until it is back)"),
        ("qtm_body_back", "qtm: body 'hull' back at frame 6 (lost since frame 3)"),
    ]


def test_silence_is_one_stall_event() -> None:
    feed = QtmFeed("2", ArenaTransform(), stall_s=0.1)
    feed.frame(0, 0, 1, (0.0, 0.0, 0.0), IDENTITY)
    feed.watch(50 * MS)
    assert feed.events == []
    feed.watch(150 * MS)
    feed.watch(250 * MS)
    feed.frame(400 * MS, 400_000, 41, (0.0, 0.0, 0.0), IDENTITY)
    codes = [e.code for e in feed.events]
    assert codes == ["qtm_stall", "qtm_drop", "qtm_stall"]
    assert feed.events[0].text == "qtm: no frame for more than 0.100 s (last frame 1)"
    assert feed.events[2].text == "qtm: no frame for 0.400 s (up to frame 41)"
    assert feed.counts.stalls == 1
    assert feed.events[0].t_ns == 150 * MS


def test_settings_refuse_nonsense() -> None:
    with pytest.raises(ValueError, match="jump_tolerance_s"):
        ClockSettings(jump_tolerance_s=0.0)
    with pytest.raises(ValueError, match="window"):
        ClockSettings(window=0)
    assert NS_PER_S == 1000 * MS
