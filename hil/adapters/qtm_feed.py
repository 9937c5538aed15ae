"""A QTM 6D frame's way to a pose sample: conversion, clock mapping, drops and losses.

No I/O here: :class:`~hil.adapters.qtm.QtmPoseSource` hands every frame it receives to a
:class:`QtmFeed` from its network thread, and the tests feed one directly.

QTM's global axes are the lab's NED world (the lab calibrates them so; VESSEL.md), its
positions are millimetres and its 6D rotation matrix maps the rigid body's FRD axes into
those. A frame becomes a :class:`~hil.core.samples.PoseSample` in
:attr:`~hil.core.samples.Frame.LAB_NED` (metres, heading), then goes through the vessel
config's :class:`~hil.adapters.frames.ArenaTransform` to the arena. Its stamp is QTM's own
timestamp (microseconds on QTM's clock) mapped onto the run's clock by
:class:`ClockMapping`. Everything worth a line in the run log is an
:class:`~hil.core.records.Event` with a ``qtm_*`` code.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, replace

from hil.adapters.frames import ArenaTransform
from hil.core.clock import NS_PER_S
from hil.core.geometry import wrap_angle
from hil.core.qtm_sample import QtmSample
from hil.core.records import Event, EventLevel
from hil.core.samples import Frame, PoseSample

NS_PER_US = 1_000
M_PER_MM = 1e-3
# A body tilted so far that its x axis is within 60 deg of vertical has no usable heading
# (|cos(pitch)| < 0.5); a floating hull never is, so such a matrix is a bad fit, not a pose.
_MIN_HEADING_NORM = 0.5


class QtmError(RuntimeError):
    """The QTM feed cannot be used: no such body, a malformed parameters XML, no qtm-rt."""


def yaw_from_rotation_matrix(matrix: Sequence[float]) -> float:
    """Return the heading (rad, wrapped to [-pi, pi)) of a QTM 6D rotation matrix.

    Args:
        matrix: The 9 floats as QTM sends them, column by column:
            (R11, R21, R31, R12, R22, R32, R13, R23, R33), R mapping body axes to the lab's.

    Returns:
        psi (rad); NaN when the matrix is not finite or the body's x axis is near vertical.

    Notes:
        With R = Rz(psi) Ry(theta) Rx(phi) (zyx convention, Fossen 2021, Eq. 2.18),
        R11 = cos(psi) cos(theta) and R21 = sin(psi) cos(theta), so psi = atan2(R21, R11)
        for any roll and any pitch below 90 deg. The column order is QTM's: the Qualisys
        drivers build their matrix as (m0, m3, m6; m1, m4, m7; m2, m5, m8).
    """
    r11, r21 = float(matrix[0]), float(matrix[1])
    if not (math.isfinite(r11) and math.isfinite(r21)) or math.hypot(r11, r21) < _MIN_HEADING_NORM:
        return math.nan
    return wrap_angle(math.atan2(r21, r11))


def lab_pose_from_6d(
    t_ns: int, position_mm: Sequence[float], matrix: Sequence[float]
) -> PoseSample | None:
    """Return the rigid body's planar pose in the lab's NED frame from a QTM 6D body.

    Args:
        t_ns: Stamp of the pose (ns on the run clock).
        position_mm: (x, y, z) of the body in QTM's (the lab's) axes (mm).
        matrix: The rotation matrix, 9 floats in QTM's column order.

    Returns:
        The pose (m, rad; :attr:`Frame.LAB_NED`), or None when QTM lost the body (NaN)
        or the matrix has no heading.
    """
    north_m, east_m = float(position_mm[0]) * M_PER_MM, float(position_mm[1]) * M_PER_MM
    yaw_rad = yaw_from_rotation_matrix(matrix)
    if not (math.isfinite(north_m) and math.isfinite(east_m) and math.isfinite(yaw_rad)):
        return None
    return PoseSample(t_ns, north_m, east_m, yaw_rad, Frame.LAB_NED)


def body_names(parameters_xml: bytes | str) -> list[str]:
    """Return the 6D rigid bodies' names in index order (``The_6D/Body/Name``).

    Raises:
        QtmError: The XML does not parse or has no ``The_6D`` section.
    """
    try:
        root = ET.fromstring(parameters_xml)
    except ET.ParseError as err:
        raise QtmError(f"QTM's 6D parameters are not XML: {err}") from err
    section = root if root.tag == "The_6D" else root.find(".//The_6D")
    if section is None:
        raise QtmError(f"QTM's parameters have no The_6D section (root {root.tag!r})")
    return [(body.findtext("Name") or "").strip() for body in section.findall("Body")]


def body_index(parameters_xml: bytes | str, name: str) -> int:
    """Return the index of rigid body `name` among QTM's 6D bodies.

    Raises:
        QtmError: No body of that name (the message lists those there are).
    """
    names = body_names(parameters_xml)
    if name not in names:
        raise QtmError(f"QTM has no 6D rigid body {name!r}; its bodies are {names!r}")
    return names.index(name)


@dataclass(frozen=True, slots=True)
class ClockSettings:
    """How QTM's timestamps are mapped onto the run clock.

    Attributes:
        window: Frames over which the offset is the minimum of arrival - QTM time.
        jump_tolerance_s: A frame that puts the offset off by more than this (s) is a jump
            of QTM's clock: an event, and the offset estimated anew from that frame on.
        settle: The first frames of a connection only estimate the offset (a late first
            frame must not read as a jump).
    """

    window: int = 200
    jump_tolerance_s: float = 0.02
    settle: int = 20

    def __post_init__(self) -> None:
        if self.window < 1 or self.settle < 0:
            raise ValueError(f"window must be >= 1 and settle >= 0, got {self!r}")
        if not (math.isfinite(self.jump_tolerance_s) and self.jump_tolerance_s > 0):
            raise ValueError(f"jump_tolerance_s must be > 0, got {self.jump_tolerance_s!r}")


class ClockMapping:
    """QTM's clock onto the run's: ``t_run_ns = t_qtm_ns + offset_ns``.

    The offset is the minimum of ``arrival_ns - t_qtm_ns`` over the last ``window`` frames
    (a monotone deque, O(1) per frame): the fastest frame bounds the transport latency from
    below, so a stamp is never after the frame's arrival and is late by at most the
    window's smallest latency (NTP's minimum-delay filter, RFC 5905 sec. 10, one way).

    A jump of QTM's clock shows as arrival - QTM time falling below the offset by more than
    the tolerance (QTM's clock leapt ahead) or as QTM time running backwards; either starts
    the estimate afresh from that frame. A window whose minimum rises by more than the
    tolerance (the fast frames aged out: QTM's clock fell behind, or the path got slower
    for a whole window) is re-estimated as well. :meth:`map` returns what happened.

    The run's own clock can be set too (the vessel computer's system clock, stepped by
    NTP): every arrival then reads late or early by the step, and the window's minimum
    would follow only once the old frames aged out, the poses mis-stamped by the step
    meanwhile. Given a steady clock read beside each arrival, a change of their
    difference beyond the tolerance is such a step, and the offset and the window move
    with it at once.

    Args:
        settings: Window and tolerance.
    """

    def __init__(self, settings: ClockSettings | None = None) -> None:
        self.settings = settings or ClockSettings()
        self._tol_ns = round(self.settings.jump_tolerance_s * NS_PER_S)
        self.reset()

    def reset(self) -> None:
        """Forget the estimate (a new connection)."""
        self._window: deque[tuple[int, int]] = deque()  # (frame count, delta ns), deltas rising
        self._count = 0
        self._last_qtm_ns: int | None = None
        self._run_minus_steady_ns: int | None = None
        self.offset_ns: int | None = None
        """The offset in force (ns), None before the first frame."""

    def _push(self, delta_ns: int) -> None:
        while self._window and self._window[-1][1] >= delta_ns:
            self._window.pop()
        self._window.append((self._count, delta_ns))
        while self._window[0][0] <= self._count - self.settings.window:
            self._window.popleft()
        self._count += 1

    def _run_clock_step(self, arrival_ns: int, steady_ns: int | None) -> int:
        """Return by how much the run clock was set since the last frame (0: not, or unknown)."""
        if steady_ns is None:
            return 0
        gap = arrival_ns - steady_ns
        last, self._run_minus_steady_ns = self._run_minus_steady_ns, gap
        if last is None or abs(gap - last) <= self._tol_ns:
            return 0
        return gap - last

    def map(self, arrival_ns: int, qtm_ns: int,
            steady_ns: int | None = None) -> tuple[int, str]:
        """Return the run-clock stamp of a frame, and "" or why the offset was re-estimated.

        Args:
            arrival_ns: When the frame arrived (ns on the run clock).
            qtm_ns: QTM's timestamp of the frame (ns on QTM's clock).
            steady_ns: A steady clock (never set, e.g. :func:`time.monotonic_ns`) read
                beside `arrival_ns`, where the run clock can be set; None: not watched.
        """
        delta = arrival_ns - qtm_ns
        why = ""
        step = self._run_clock_step(arrival_ns, steady_ns)
        if step and self.offset_ns is not None:
            self._window = deque((n, d + step) for n, d in self._window)
            self.offset_ns += step
            why = f"the run's clock was set by {step / NS_PER_S:+.3f} s (the offset moved with it)"
        previous = self.offset_ns
        settled = self._count >= self.settings.settle
        if previous is not None and settled and self._last_qtm_ns is not None and not why:
            if qtm_ns <= self._last_qtm_ns:
                why = f"QTM time ran back by {(self._last_qtm_ns - qtm_ns) / NS_PER_S:.3f} s"
            elif delta < previous - self._tol_ns:
                why = f"QTM time leapt ahead by {(previous - delta) / NS_PER_S:.3f} s"
        if why and not step:
            self.reset()
        self._last_qtm_ns = qtm_ns
        self._push(delta)
        self.offset_ns = self._window[0][1]
        if (not why and previous is not None and settled
                and self.offset_ns > previous + self._tol_ns):
            why = (f"the offset rose by {(self.offset_ns - previous) / NS_PER_S:.3f} s over "
                   f"{self.settings.window} frames")
        return qtm_ns + self.offset_ns, why


@dataclass(frozen=True, slots=True)
class QtmCounters:
    """What the QTM feed counted since the source was created.

    Attributes:
        frames: Data frames received.
        poses: Pose samples delivered (the body seen, finite).
        lost: Frames in which the body was lost (NaN) or had no heading.
        drops: Frame numbers skipped within a stream (frames QTM never sent us).
        clock_jumps: Re-estimations of the clock offset after a jump.
        stalls: Silences longer than the stall threshold.
        connects: Connections that reached streaming.
        disconnects: Connections lost.
        connect_failures: Connection attempts that failed (refused, no such body, error).
        last_drop_rate: The 6D component's drop rate in the newest frame (QTM's own).
    """

    frames: int = 0
    poses: int = 0
    lost: int = 0
    drops: int = 0
    clock_jumps: int = 0
    stalls: int = 0
    connects: int = 0
    disconnects: int = 0
    connect_failures: int = 0
    last_drop_rate: int = 0


class QtmFeed:
    """The state of one QTM pose feed: frame numbers, losses, silences and the clock.

    Args:
        body: The rigid body's name (for the events' texts).
        transform: Lab NED world and mocap body to the arena and the vessel's body origin.
        clock: Settings of the clock mapping.
        stall_s: A silence longer than this (s) is a stall event.
    """

    def __init__(self, body: str, transform: ArenaTransform,
                 clock: ClockSettings | None = None, stall_s: float = 0.1) -> None:
        self.body = body
        self.transform = transform
        self.clock = ClockMapping(clock)
        self._stall_ns = round(stall_s * NS_PER_S)
        self.counts = QtmCounters()
        self.events: list[Event] = []
        self.samples: list[QtmSample] = []
        """Every frame taken, as received (for the run log); the owner empties it."""
        self._last_frame: int | None = None
        self._last_arrival_ns: int | None = None
        self._silent_reported = False
        self._lost_since: int | None = None

    def _count(self, **increments: int) -> None:
        self.counts = replace(self.counts, **{
            name: getattr(self.counts, name) + n for name, n in increments.items()})

    def event(self, t_ns: int, level: EventLevel, code: str, text: str, **counts: int) -> None:
        """Record an event (and count what `counts` names)."""
        self.events.append(Event(max(0, t_ns), level, code, f"qtm: {text}"))
        if counts:
            self._count(**counts)

    def restart(self) -> None:
        """Start a new stream (a new connection): frame numbers and clock start over."""
        self.clock.reset()
        self._last_frame = None
        self._last_arrival_ns = None
        self._silent_reported = False

    def frame(self, arrival_ns: int, timestamp_us: int, frame_number: int,
              position_mm: Sequence[float], matrix: Sequence[float],
              drop_rate: int = 0, out_of_sync_rate: int = 0,
              body_index: int = -1, steady_ns: int | None = None) -> PoseSample | None:
        """Take one received frame of the body; return its arena pose, or None if lost.

        Args:
            arrival_ns: When it arrived (ns on the run clock).
            timestamp_us: QTM's timestamp (us).
            frame_number: QTM's frame number.
            position_mm: The body's (x, y, z) (mm, QTM's axes).
            matrix: Its rotation matrix (9 floats, QTM's column order).
            drop_rate: The 6D component's drop rate field, kept in the counters.
            out_of_sync_rate: The 6D component's out-of-sync rate field.
            body_index: The body's index among QTM's 6D bodies (-1: not told).
            steady_ns: A steady clock read beside `arrival_ns` where the run clock can be
                set (:meth:`ClockMapping.map`); None: not watched.

        Every frame is also kept in :attr:`samples` as received.
        """
        self._count(frames=1)
        self._check_sequence(arrival_ns, frame_number)
        t_ns, why = self.clock.map(arrival_ns, timestamp_us * NS_PER_US, steady_ns)
        if why:
            self.event(arrival_ns, EventLevel.WARN, "qtm_clock_jump",
                       f"clock offset re-estimated at frame {frame_number}: {why}",
                       clock_jumps=1)
        lab = lab_pose_from_6d(t_ns, position_mm, matrix)
        if self.counts.last_drop_rate != drop_rate:
            self.counts = replace(self.counts, last_drop_rate=drop_rate)
        self._keep(t_ns, timestamp_us, frame_number, position_mm, matrix,
                   (drop_rate, out_of_sync_rate, body_index), lost=lab is None)
        if lab is None:
            if self._lost_since is None:
                self._lost_since = frame_number
                self.event(arrival_ns, EventLevel.WARN, "qtm_body_lost",
                           f"body {self.body!r} lost at frame {frame_number} "
                           "(no pose until it is back)")
            self._count(lost=1)
            return None
        if self._lost_since is not None:
            self.event(arrival_ns, EventLevel.INFO, "qtm_body_back",
                       f"body {self.body!r} back at frame {frame_number} "
                       f"(lost since frame {self._lost_since})")
            self._lost_since = None
        self._count(poses=1)
        return self.transform.to_arena(lab)

    def _keep(self, t_ns: int, timestamp_us: int, frame_number: int,
              position_mm: Sequence[float], matrix: Sequence[float],
              fields: tuple[int, int, int], lost: bool) -> None:
        """Keep the frame as received; `fields`: drop rate, out-of-sync rate, body index."""
        x, y, z = (float(v) for v in position_mm)
        self.samples.append(QtmSample(
            max(0, t_ns), timestamp_us, max(0, frame_number), fields[2], self.body, (x, y, z),
            tuple(float(v) for v in matrix), math.nan, fields[0], fields[1],
            self.counts.drops, self.counts.lost + int(lost)))  # fmt: skip

    def _check_sequence(self, arrival_ns: int, frame_number: int) -> None:
        last, self._last_frame = self._last_frame, frame_number
        if last is not None:
            if frame_number > last + 1:
                missing = frame_number - last - 1
                span = f"{last + 1}" if missing == 1 else f"{last + 1}..{frame_number - 1}"
                self.event(arrival_ns, EventLevel.WARN, "qtm_drop",
                           f"{missing} frame(s) dropped ({span})", drops=missing)
            elif frame_number <= last:
                self.event(arrival_ns, EventLevel.WARN, "qtm_frames_restarted",
                           f"frame number went back from {last} to {frame_number} "
                           "(a new measurement in QTM?)")
        before, self._last_arrival_ns = self._last_arrival_ns, arrival_ns
        if before is not None and arrival_ns - before > self._stall_ns:
            self.event(arrival_ns, EventLevel.WARN, "qtm_stall",
                       f"no frame for {(arrival_ns - before) / NS_PER_S:.3f} s "
                       f"(up to frame {frame_number})", stalls=0 if self._silent_reported else 1)
        self._silent_reported = False

    def watch(self, now_ns: int) -> None:
        """Record a stall once while the stream is silent for longer than the threshold."""
        last = self._last_arrival_ns
        if last is not None and not self._silent_reported and now_ns - last > self._stall_ns:
            self._silent_reported = True
            self.event(now_ns, EventLevel.WARN, "qtm_stall",
                       f"no frame for more than {self._stall_ns / NS_PER_S:.3f} s "
                       f"(last frame {self._last_frame})", stalls=1)

