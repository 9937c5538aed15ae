"""The recorded backend: a hil bag served through the adapters against a simulated clock.

:func:`read_log` reads a recorded run (rosbag2 MCAP, see :mod:`hil.bag`) once,
into numpy columns for the high-rate streams and records for the rest, and
checks it on the way: non-finite messages are skipped with a warning,
duplicated samples are dropped with a warning, out-of-order stamps are served
in recorded order (a warning says how many). :class:`LogWorld` then serves the
samples to :class:`hil.runtime.loop.Runtime` unchanged: a poll at time t returns
every sample whose delivery time (stamp plus the sensor's delivery delay) lies
before t, in recorded order, as the simulated world delivers them; the thruster
sink captures what the stack sends, and fails where the recording says the link
failed, so the loop takes the same fault path.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hil.adapters.interfaces import ThrusterSinkError
from hil.bag import topics
from hil.bag.columns import Columns, to_columns
from hil.bag.errors import BagError
from hil.bag.messages import Record, to_record
from hil.bag.reader import BagInfo, BagReader
from hil.bag.storage import RawMessage
from hil.core.clock import SimClock
from hil.core.records import Decision, Event
from hil.core.samples import ImuSample, ObstacleLayout, PoseSample, ThrusterCommand

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

THRUSTER_FAILURE_CODE = "thruster_failure"
"""Event code the runtime logs when a thruster command cannot be delivered."""

_COLUMN_TOPICS: dict[str, tuple[str, ...]] = {
    topics.POSE: ("x_m", "y_m", "yaw_rad"),
    topics.IMU: ("accel_x_mps2", "accel_y_mps2", "yaw_rate_radps"),
    topics.ODOM: ("x_m", "y_m", "yaw_rad", "surge_mps", "sway_mps", "yaw_rate_radps"),
    topics.VELOCITY_COMMAND: ("surge_mps", "sway_mps", "yaw_rate_radps"),
    topics.THRUSTERS: ("tunnel", "port", "starboard", "port_angle_rad", "starboard_angle_rad"),
}
_RECORD_TOPICS = (topics.DECISION, topics.OBSTACLES, topics.EVENTS)


class LogDataError(BagError):
    """A recorded run that cannot be served: a stream missing or in the wrong frame."""


@dataclass(frozen=True, slots=True)
class Stream:
    """One high-rate topic as columns.

    Attributes:
        t_ns: Stamps (ns), shape (N,), in recorded order.
        values: Values, shape (N, k), time-major; the fields of :data:`_COLUMN_TOPICS`.
    """

    t_ns: IntArray
    values: FloatArray

    def __len__(self) -> int:
        return len(self.t_ns)

    @staticmethod
    def empty(k: int) -> Stream:
        """Return an empty stream with `k` fields."""
        return Stream(np.zeros(0, np.int64), np.zeros((0, k)))


@dataclass(frozen=True)
class RecordedRun:
    """Everything a replay needs of one recorded run.

    Attributes:
        path: The bag.
        info: Its summary (topics, custom data, problems).
        poses: Pose (x m, y m, psi rad), shape (N, 3).
        imus: IMU (ax m/s^2, ay m/s^2, r rad/s), shape (N, 3).
        estimates: Observer estimates (x, y, psi, u, v, r), shape (N, 6).
        references: Velocity references (u m/s, v m/s, r rad/s), shape (N, 3).
        thrusters: Thruster commands (tunnel, port, starboard, port angle rad,
            starboard angle rad), shape (N, 5).
        decisions: The symbolic controller's decisions, in time order.
        layouts: Obstacle layouts as recorded (only when they changed).
        events: Runtime events and faults.
        warnings: What was skipped or odd while reading, one line each.
    """

    path: Path
    info: BagInfo
    poses: Stream
    imus: Stream
    estimates: Stream
    references: Stream
    thrusters: Stream
    decisions: tuple[Decision, ...]
    layouts: tuple[ObstacleLayout, ...]
    events: tuple[Event, ...]
    warnings: tuple[str, ...]

    @property
    def end_ns(self) -> int:
        """Latest time in the run (ns); 0 when empty."""
        streams = (self.poses, self.imus, self.estimates, self.thrusters)
        ends = [int(s.t_ns.max()) for s in streams if len(s)]
        ends += [d.t_ns for d in self.decisions[-1:]]
        return max(ends, default=0)

    def thruster_failures_ns(self) -> frozenset[int]:
        """Return the times (ns) at which a thruster command could not be delivered."""
        return frozenset(e.t_ns for e in self.events if e.code == THRUSTER_FAILURE_CODE)


def _tidy(topic: str, stream: Stream, warnings: list[str]) -> Stream:
    """Drop exact duplicates and report out-of-order stamps (kept in recorded order)."""
    if len(stream) < 2:
        return stream
    same_t = stream.t_ns[1:] == stream.t_ns[:-1]
    same_v = np.all(stream.values[1:] == stream.values[:-1], axis=1)
    duplicate = np.concatenate([[False], same_t & same_v])
    if duplicate.any():
        first = int(stream.t_ns[np.flatnonzero(duplicate)[0]])
        warnings.append(
            f"{topic}: dropped {int(duplicate.sum())} duplicated message(s), first at t={first} ns"
        )
        stream = Stream(stream.t_ns[~duplicate], stream.values[~duplicate])
    clash = np.flatnonzero(stream.t_ns[1:] == stream.t_ns[:-1])
    if clash.size:
        warnings.append(
            f"{topic}: {clash.size} message(s) share a stamp with different values, "
            f"first at t={int(stream.t_ns[clash[0]])} ns; served in recorded order"
        )
    back = np.flatnonzero(stream.t_ns[1:] < stream.t_ns[:-1])
    if back.size:
        warnings.append(
            f"{topic}: {back.size} stamp(s) go back in time, first at "
            f"t={int(stream.t_ns[back[0] + 1])} ns after t={int(stream.t_ns[back[0]])} ns; "
            "served in recorded order"
        )
    return stream


def _stream(
    reader: BagReader,
    topic: str,
    raws: list[RawMessage],
    fields: tuple[str, ...],
    warnings: list[str],
) -> Stream:
    info = {t.name: t for t in reader.info.topics}.get(topic)
    if info is None or not info.decodable:
        return Stream.empty(len(fields))
    skipped: list[str] = []

    def decode_one(raw: RawMessage) -> Record | None:
        try:
            return to_record(raw.msgtype, reader.decode(raw))
        except ValueError as err:  # BagError, SampleError and RecordValueError all are
            skipped.append(f"t={raw.t_ns} ns: {str(err).splitlines()[0]}")
            return None

    try:
        columns: Columns = to_columns(topic, info.msgtype, raws, decode_one)
    except BagError as err:
        raise LogDataError(f"{str(reader.path)!r}: {err}") from err
    if skipped:
        warnings.append(
            f"{topic}: skipped {len(skipped)} message(s) that do not decode to valid "
            f"samples, first {skipped[0]}"
        )
    if topic == topics.POSE and columns.frame_id not in ("", "arena") and len(columns.t_ns):
        raise LogDataError(
            f"{str(reader.path)!r}: poses are in frame {columns.frame_id!r}; "
            "replay needs arena-frame poses"
        )
    values = columns.stack(*fields) if len(columns.t_ns) else np.zeros((0, len(fields)))
    return _tidy(topic, Stream(columns.t_ns, values), warnings)


def _records(reader: BagReader, warnings: list[str]) -> list[tuple[str, int, Record]]:
    present = {t.name for t in reader.info.topics}
    wanted = [t for t in _RECORD_TOPICS if t in present]
    before = len(reader.skipped)
    out = list(reader.records(wanted, on_error="skip")) if wanted else []
    warnings.extend(
        f"{skip.topic}: skipped the message at t={skip.t_ns} ns: {skip.reason.splitlines()[0]}"
        for skip in reader.skipped[before:]
    )
    return out


def read_log(path: str | Path) -> RecordedRun:
    """Read a recorded hil run; never modifies it.

    Args:
        path: Bag directory or bare ``.mcap`` file.

    Returns:
        The run, with warnings for what was skipped.

    Raises:
        BagError: The path is missing, not a bag, or not a hil run (see
            :class:`hil.bag.reader.BagReader`).
        LogDataError: A stream cannot be used (poses in a non-arena frame).
    """
    warnings: list[str] = []
    with BagReader(path) as reader:
        reader.require_hil_run()
        info = reader.info
        warnings.extend(f"bag: {p}" for p in info.problems)
        warnings.extend(
            f"{t.name}: cannot be decoded: {t.problem}"
            for t in info.topics
            if not t.decodable and t.name in topics.HIL_TOPICS
        )
        raws: dict[str, list[RawMessage]] = {topic: [] for topic in _COLUMN_TOPICS}
        for raw in reader.messages(list(_COLUMN_TOPICS)):  # one pass over the chunks
            raws[raw.topic].append(raw)
        streams = {
            topic: _stream(reader, topic, raws[topic], fields, warnings)
            for topic, fields in _COLUMN_TOPICS.items()
        }
        records = _records(reader, warnings)
    decisions = [r for _, _, r in records if isinstance(r, Decision)]
    decisions.sort(key=lambda d: d.t_ns)
    layouts = [r for _, _, r in records if isinstance(r, ObstacleLayout)]
    events = [r for _, _, r in records if isinstance(r, Event)]
    return RecordedRun(
        path=Path(path),
        info=info,
        poses=streams[topics.POSE],
        imus=streams[topics.IMU],
        estimates=streams[topics.ODOM],
        references=streams[topics.VELOCITY_COMMAND],
        thrusters=streams[topics.THRUSTERS],
        decisions=tuple(decisions),
        layouts=tuple(layouts),
        events=tuple(events),
        warnings=tuple(warnings),
    )


@dataclass(frozen=True, slots=True)
class LogConfig:
    """How recorded samples are delivered.

    Attributes:
        pose_delay_ns: Time from a pose's stamp to its delivery (ns); the
            simulated motion-capture latency (10 ms) by default. The recorder
            stores stamps, not arrival times, so the delay is configuration.
        imu_delay_ns: Same for the IMU (ns).
    """

    pose_delay_ns: int = 10_000_000
    imu_delay_ns: int = 0

    def __post_init__(self) -> None:
        for name in ("pose_delay_ns", "imu_delay_ns"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 0):
                raise ValueError(f"log config {name!r} must be an integer >= 0, got {value!r}")


def _delivery(t_ns: IntArray, delay_ns: int) -> IntArray:
    """Delivery time of each sample: a late stamp is delivered with its predecessor."""
    if not len(t_ns):
        return t_ns
    return np.maximum.accumulate(t_ns) + delay_ns


class LogPoseSource:
    """Recorded poses, delivered once the clock has passed their delivery time."""

    def __init__(self, clock: SimClock, stream: Stream, delay_ns: int) -> None:
        self._clock = clock
        self._stream = stream
        self._due = _delivery(stream.t_ns, delay_ns)
        self._next = 0

    def poll(self) -> list[PoseSample]:
        """Return the poses delivered since the last call, in recorded order."""
        end = int(np.searchsorted(self._due, self._clock.now_ns(), side="left"))
        t, v = self._stream.t_ns, self._stream.values
        out = [
            PoseSample(int(t[i]), float(v[i, 0]), float(v[i, 1]), float(v[i, 2]))
            for i in range(self._next, end)
        ]
        self._next = max(self._next, end)
        return out


class LogImuSource:
    """Recorded IMU samples, delivered once the clock has passed their delivery time."""

    def __init__(self, clock: SimClock, stream: Stream, delay_ns: int) -> None:
        self._clock = clock
        self._stream = stream
        self._due = _delivery(stream.t_ns, delay_ns)
        self._next = 0

    def poll(self) -> list[ImuSample]:
        """Return the IMU samples delivered since the last call, in recorded order."""
        end = int(np.searchsorted(self._due, self._clock.now_ns(), side="left"))
        t, v = self._stream.t_ns, self._stream.values
        out = [
            ImuSample(int(t[i]), float(v[i, 0]), float(v[i, 1]), float(v[i, 2]))
            for i in range(self._next, end)
        ]
        self._next = max(self._next, end)
        return out


class LogObstacleSource:
    """The recorded obstacle layouts: the newest one stamped at or before now.

    Before the first recorded layout the first one is served (the recorder logs
    the layout the stack started with at its first tick).
    """

    def __init__(self, clock: SimClock, layouts: tuple[ObstacleLayout, ...]) -> None:
        if not layouts:
            raise LogDataError("the log holds no obstacle layout; the stack cannot run on it")
        self._clock = clock
        self._layouts = layouts
        self._t_ns = np.maximum.accumulate(np.array([x.t_ns for x in layouts], dtype=np.int64))

    def latest(self) -> ObstacleLayout:
        """Return the newest layout recorded at or before the clock's time."""
        i = int(np.searchsorted(self._t_ns, self._clock.now_ns(), side="right")) - 1
        return self._layouts[max(i, 0)]


class CapturingThrusterSink:
    """Captures the commands the stack sends; fails where the recording's link failed.

    Args:
        failures_ns: Command times (ns) at which delivery failed in the recording.
    """

    def __init__(self, failures_ns: frozenset[int] = frozenset()) -> None:
        self.commands: list[ThrusterCommand] = []
        self._failures_ns = failures_ns

    def send(self, command: ThrusterCommand) -> None:
        """Capture `command`, or raise ThrusterSinkError where the recording failed."""
        if command.t_ns in self._failures_ns:
            raise ThrusterSinkError(f"thruster link failed at t={command.t_ns} ns in the recording")
        self.commands.append(command)

    def as_array(self) -> tuple[IntArray, FloatArray]:
        """Return the captured (t_ns (N,), commands (N, 5)) in the recorded stream's layout."""
        t = np.array([c.t_ns for c in self.commands], dtype=np.int64)
        values = np.array(
            [
                (c.tunnel, c.port, c.starboard, c.port_angle_rad, c.starboard_angle_rad)
                for c in self.commands
            ],
            dtype=np.float64,
        ).reshape(-1, 5)
        return t, values


class LogWorld:
    """A recorded run behind the adapters, on a simulated clock starting at 0.

    Args:
        run: The recorded run.
        config: Delivery delays.
    """

    def __init__(self, run: RecordedRun, config: LogConfig | None = None) -> None:
        config = config or LogConfig()
        self.run = run
        self.clock = SimClock(0)
        self.pose = LogPoseSource(self.clock, run.poses, config.pose_delay_ns)
        self.imu = LogImuSource(self.clock, run.imus, config.imu_delay_ns)
        self.obstacles = LogObstacleSource(self.clock, run.layouts)
        self.thrusters = CapturingThrusterSink(run.thruster_failures_ns())
