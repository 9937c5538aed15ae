"""A recorded run as numpy arrays, for pictures and Rerun export.

:func:`load_run` reads a bag once with :class:`~hil.bag.reader.BagReader` and
keeps every stream hil records as time-major arrays (``t_ns`` of shape (N,),
values of shape (N, k)), plus the few variable-size records (decisions, obstacle
layouts, events) as tuples. Fixed-layout topics are decoded in bulk
(:func:`hil.bag.columns.to_columns`), so a 3-minute run loads in well under a
second. The log is only read, never modified.

A message that does not decode is skipped and listed in :attr:`RunData.skipped`,
so one damaged message does not hide the rest of a run; a log that is not a hil
run, or holds no pose, raises a :class:`~hil.bag.errors.BagError`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hil.bag import topics
from hil.bag.columns import Columns, to_columns
from hil.bag.errors import BagError, NotAHilRunError
from hil.bag.messages import Record, to_record
from hil.bag.reader import BagInfo, BagReader, SkippedMessage
from hil.bag.recorder import RunInfo
from hil.bag.storage import RawMessage
from hil.core.records import Decision, Event
from hil.core.samples import ObstacleLayout
from hil.core.shapes import Rect

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

_SYNTHESIS_TEXT = re.compile(r"controller v(\d+) in ([0-9.eE+-]+) s")
_CONTROLLER_READY = "controller_ready"


@dataclass(frozen=True, slots=True)
class Series:
    """One stream as columns.

    Attributes:
        t_ns: Sample times (ns on the run clock), shape (N,), int64, ascending.
        values: Values, shape (N, k), time-major; the column order is documented
            where the series is named (see :class:`RunData`).
    """

    t_ns: IntArray
    values: FloatArray

    def __len__(self) -> int:
        """Return the number of samples N."""
        return int(self.t_ns.shape[0])

    @property
    def t_s(self) -> FloatArray:
        """Return the sample times in seconds, shape (N,)."""
        return self.t_ns.astype(np.float64) / 1e9

    @staticmethod
    def empty(k: int) -> Series:
        """Return a series without samples and `k` value columns."""
        return Series(np.zeros(0, np.int64), np.zeros((0, k)))


@dataclass(frozen=True, slots=True)
class Layout:
    """One recorded obstacle layout with the polygons as drawn.

    Attributes:
        t_ns: Time the layout was observed (ns).
        real: Real obstacle outlines, each shape (n, 2), columns (x, y) in m.
        inflated: Inflated outlines the synthesis used, as recorded (may be empty).
        rectangles: The real obstacles as axis-aligned rectangles (what the
            controller is synthesized from).
    """

    t_ns: int
    real: tuple[FloatArray, ...]
    inflated: tuple[FloatArray, ...]
    rectangles: tuple[Rect, ...]

    def as_obstacle_layout(self) -> ObstacleLayout:
        """Return the layout as the adapters' record."""
        return ObstacleLayout(self.t_ns, self.rectangles)


@dataclass(frozen=True, slots=True)
class SynthesisTime:
    """One re-synthesis, read from a ``controller_ready`` event.

    Attributes:
        t_ns: Time the controller was swapped in (ns).
        version: Controller version.
        seconds: Wall time of the synthesis (s).
    """

    t_ns: int
    version: int
    seconds: float


def synthesis_time(event: Event) -> SynthesisTime | None:
    """Return the synthesis an event reports ("controller vN in S s"), or None."""
    if event.code != _CONTROLLER_READY:
        return None
    match = _SYNTHESIS_TEXT.search(event.text)
    if match is None:
        return None
    seconds = float(match.group(2))
    return (
        SynthesisTime(event.t_ns, int(match.group(1)), seconds) if math.isfinite(seconds) else None
    )


@dataclass(frozen=True, slots=True)
class RunData:
    """A recorded run, every stream as arrays.

    Attributes:
        path: The log that was read.
        info: The log's summary.
        pose: Measured poses, values (N, 3): x m, y m, psi rad.
        estimate: Observer estimate, values (N, 6): x m, y m, psi rad, u m/s, v m/s, r rad/s.
        reference: Velocity reference nu_ref, values (N, 3): u m/s, v m/s, r rad/s.
        force: Force demand tau, values (N, 3): X N, Y N, N N m.
        thrusters: Thruster commands, values (N, 5): tunnel, port, starboard in [-1, 1],
            port and starboard azimuth angles in rad.
        decisions: The symbolic controller's decisions, in time order.
        layouts: The obstacle layouts, in time order.
        events: Runtime events and faults, in time order.
        skipped: Messages that did not decode and were left out.
    """

    path: Path
    info: BagInfo
    pose: Series
    estimate: Series
    reference: Series
    force: Series
    thrusters: Series
    decisions: tuple[Decision, ...]
    layouts: tuple[Layout, ...]
    events: tuple[Event, ...]
    skipped: tuple[SkippedMessage, ...] = ()

    @property
    def run(self) -> RunInfo | None:
        """Return what produced the run (scenario, seed), or None when not stored."""
        return self.info.run

    @property
    def start_ns(self) -> int:
        """Return the first log time (ns); 0 for an empty log."""
        return self.info.start_ns or 0

    @property
    def end_ns(self) -> int:
        """Return the last log time (ns); 0 for an empty log."""
        return self.info.end_ns or 0

    def synthesis_times(self) -> tuple[SynthesisTime, ...]:
        """Return each re-synthesis with its wall time, from the ``controller_ready`` events."""
        times = (synthesis_time(event) for event in self.events)
        return tuple(t for t in times if t is not None)

    def layout_at(self, t_ns: int) -> Layout | None:
        """Return the newest layout observed at or before `t_ns` (else the first, or None)."""
        if not self.layouts:
            return None
        best = self.layouts[0]
        for layout in self.layouts:
            if layout.t_ns <= t_ns:
                best = layout
        return best


_FIELDS: dict[str, tuple[str, ...]] = {
    topics.POSE: ("x_m", "y_m", "yaw_rad"),
    topics.ODOM: ("x_m", "y_m", "yaw_rad", "surge_mps", "sway_mps", "yaw_rate_radps"),
    topics.VELOCITY_COMMAND: ("surge_mps", "sway_mps", "yaw_rate_radps"),
    topics.FORCE_COMMAND: ("surge_n", "sway_n", "yaw_nm"),
    topics.THRUSTERS: ("tunnel", "port", "starboard", "port_angle_rad", "starboard_angle_rad"),
}
_RECORD_TOPICS = (topics.DECISION, topics.EVENTS)
_DRAWN = frozenset({*_FIELDS, *_RECORD_TOPICS, topics.OBSTACLES})


def _polygon(msg: Any) -> FloatArray:
    xs = np.asarray(msg.x, dtype=np.float64).reshape(-1)
    ys = np.asarray(msg.y, dtype=np.float64).reshape(-1)
    if xs.shape != ys.shape or xs.size < 3 or not np.all(np.isfinite(xs) & np.isfinite(ys)):
        raise ValueError(f"obstacle polygon {msg.name!r} has x={xs.tolist()!r}, y={ys.tolist()!r}")
    return np.column_stack([xs, ys])


class _Loader:
    """One pass over a bag, grouping raw messages by topic."""

    def __init__(self, reader: BagReader) -> None:
        self.reader = reader
        self.skipped: list[SkippedMessage] = []

    def _skip(self, raw: RawMessage, err: Exception) -> None:
        self.skipped.append(SkippedMessage(raw.topic, raw.t_ns, str(err)))

    def record(self, raw: RawMessage) -> Record | None:
        return to_record(raw.msgtype, self.reader.decode(raw))

    def safe(self, raw: RawMessage, fn: Callable[[RawMessage], Any]) -> Any:
        try:
            return fn(raw)
        except (BagError, ValueError) as err:
            self._skip(raw, err)
            return None

    def columns(self, topic: str, raws: list[RawMessage]) -> Series:
        names = _FIELDS[topic]
        if not raws:
            return Series.empty(len(names))
        try:
            cols: Columns = to_columns(topic, raws[0].msgtype, raws, self.record)
        except (BagError, ValueError):
            # A bad message somewhere: decode one by one and skip the bad ones.
            records = [r for r in (self.safe(raw, self.record) for raw in raws) if r is not None]
            t_ns = np.array([r.t_ns for r in records], dtype=np.int64)
            values = np.array(
                [[getattr(r, n) for n in names] for r in records], dtype=np.float64
            ).reshape(len(records), len(names))
            return Series(t_ns, values)
        return Series(cols.t_ns, cols.stack(*names))

    def layout(self, raw: RawMessage) -> Layout:
        msg = self.reader.decode(raw)
        record = to_record(raw.msgtype, msg)
        assert isinstance(record, ObstacleLayout)
        real = tuple(_polygon(p) for p in msg.real)
        inflated = tuple(_polygon(p) for p in msg.inflated)
        return Layout(record.t_ns, real, inflated, record.obstacles)


def load_run(path: str | Path) -> RunData:
    """Read a recorded run.

    Args:
        path: Bag directory or ``.mcap`` file written by hil's recorder.

    Returns:
        The run's streams as arrays.

    Raises:
        BagNotFoundError: The path does not exist.
        BagFormatError: Not a readable bag (truncated beyond use, foreign storage, ...).
        NotAHilRunError: A valid log without hil's topics, or without a single pose.
    """
    with BagReader(path) as reader:
        reader.require_hil_run()
        info = reader.info
        # The IMU and the lab's per-thruster topics are not drawn (/hil/thrusters is lossless).
        wanted = [t.name for t in info.topics if t.decodable and t.name in _DRAWN]
        by_topic: dict[str, list[RawMessage]] = {name: [] for name in wanted}
        for raw in reader.messages(wanted):
            by_topic[raw.topic].append(raw)
        loader = _Loader(reader)
        series = {topic: loader.columns(topic, by_topic.get(topic, [])) for topic in _FIELDS}
        records: dict[str, list[Any]] = {t: [] for t in _RECORD_TOPICS}
        for topic in _RECORD_TOPICS:
            for raw in by_topic.get(topic, []):
                record = loader.safe(raw, loader.record)
                if record is not None:
                    records[topic].append(record)
        layouts = [
            layout
            for layout in (
                loader.safe(raw, loader.layout) for raw in by_topic.get(topics.OBSTACLES, [])
            )
            if layout is not None
        ]
    if not len(series[topics.POSE]) and not len(series[topics.ODOM]):
        raise NotAHilRunError(
            f"{str(path)!r} holds no pose and no state estimate "
            f"({topics.POSE!r}, {topics.ODOM!r}): nothing to show"
        )
    return RunData(
        path=Path(path),
        info=info,
        pose=series[topics.POSE],
        estimate=series[topics.ODOM],
        reference=series[topics.VELOCITY_COMMAND],
        force=series[topics.FORCE_COMMAND],
        thrusters=series[topics.THRUSTERS],
        decisions=tuple(records[topics.DECISION]),
        layouts=tuple(layouts),
        events=tuple(records[topics.EVENTS]),
        skipped=tuple(loader.skipped),
    )
