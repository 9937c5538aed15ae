"""The one loader of a recorded run: every stream hil records as numpy arrays.

:func:`load_run` reads a bag once with :class:`~hil.bag.reader.BagReader` and
returns a :class:`RunData`: the fixed-layout streams (:data:`FIELDS`, the one
field table) as time-major arrays (``t_ns`` of shape (N,), values of shape
(N, k)), decoded in bulk (:func:`hil.bag.columns.to_columns`), and the
variable-size records (decisions, obstacle layouts, events) as tuples. The log
backend (:mod:`hil.adapters.log`), replay, the Rerun export and the plots all
read a run through it, so they see the same samples. The log is only read,
never modified.

The rule for imperfect input, the same on every topic:

- *bad* messages (a payload that does not decode, a value a sample refuses such
  as NaN) are left out;
- *out-of-order* messages (a stamp earlier than the one before it on the same
  topic) are put in stamp order (a stable sort: messages with equal stamps keep
  their recorded order);
- *duplicates* (same topic, same stamp, same values) are dropped but the first;
  messages that share a stamp with different values are all kept (on a sample
  stream that is odd and reported; several events or decisions at one tick are not);
- each of these is counted per topic and reported in :attr:`RunData.repairs`
  (one line each in :attr:`RunData.warnings`, naming the first time), so no
  recorded data is lost silently; every bad message is also listed in
  :attr:`RunData.skipped`.

A stream must be in one frame, and poses in the arena frame, else
:class:`~hil.bag.errors.FrameError`. A log that is not a hil run raises
:class:`~hil.bag.errors.NotAHilRunError`.

Both layouts of hil's logs are read, told apart by their topics: a log of hil format 3
holds hil's arena pose, estimate and stamped commands on ``/hil/...``
(:data:`~hil.bag.topics.STREAM_TOPICS`), and the streams are read from there (the lab's
topics beside them hold the pose in the lab's frame and the unstamped commands); a log
of format 2 holds them on the lab's names, read as before. ``/tf_static`` gives
:attr:`RunData.lab_frame`, ``/hil/qtm/6d`` :attr:`RunData.qtm`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from hil.bag import field_table as ft
from hil.bag import topics
from hil.bag.columns import to_columns
from hil.bag.decoding import lab_frame_from_tf, to_record
from hil.bag.errors import BagError, FrameError, NotAHilRunError, OldLogFormatError
from hil.bag.lab_frame import LabFrame
from hil.bag.lab_streams import (
    LAB_POSE_FRAME,
    UNSTAMPED_TYPES,
    LabTopics,
    thrusters_from_wrenches,
    unstamped_values,
)
from hil.bag.messages import Record
from hil.bag.reader import BagInfo, BagReader, SkippedMessage
from hil.bag.repairs import Repair, RepairKind, tidy
from hil.bag.run_info import RunInfo
from hil.bag.storage import RawMessage
from hil.core.arrays import FloatArray, IntArray
from hil.core.qtm_sample import QtmSample
from hil.core.records import ControllerReady, ControllerSource, Decision, Event
from hil.core.samples import ObstacleLayout
from hil.core.shapes import Rect
from hil.core.timeline import in_force
from hil.core.tracking import TrackingSeries, tracking_error

_LEGACY_READY = re.compile(r"controller v(\d+)\b( early)?(?: in ([0-9.eE+-]+) s)?")
_CONTROLLER_READY = "controller_ready"

FIELDS: dict[str, tuple[str, ...]] = {
    topics.POSE: ft.POSE.names,
    topics.IMU: ft.IMU.names,
    topics.ODOM: ft.ODOM.names,
    topics.VELOCITY_COMMAND: ft.TWIST_STAMPED.names,
    topics.FORCE_COMMAND: ft.WRENCH_STAMPED.names,
    topics.THRUSTERS: ft.THRUSTERS.names,
}
"""Topic -> the sample fields kept, in column order: the field table's
(:mod:`hil.bag.field_table`) for each stream."""

RECORD_TOPICS = (topics.DECISION, topics.OBSTACLES, topics.EVENTS, topics.CONTROLLERS)
"""Topics read as records (variable size)."""

WRENCH_TOPICS = (topics.THRUSTER_TUNNEL, topics.THRUSTER_PORT, topics.THRUSTER_STARBOARD)
"""The lab's per-thruster commands, read when ``/hil/thrusters`` is absent."""

_POSE_FRAMES = ("", topics.ARENA_FRAME)


@dataclass(frozen=True, slots=True)
class Series:
    """One stream as columns.

    Attributes:
        t_ns: Sample times (ns on the run clock), shape (N,), int64, ascending.
        values: Values, shape (N, k), time-major; the columns of :data:`FIELDS`.
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


def legacy_controller_ready(event: Event) -> ControllerReady | None:
    """Return the controller a ``controller_ready`` event of a log without /hil/controllers names.

    Logs written before the record said it only in words: "controller vN in S s" (the
    regression suite leaves " in S s" out) or "controller vN early in S s: ...". The
    source, report age and layout were not recorded.
    """
    match = _LEGACY_READY.match(event.text) if event.code == _CONTROLLER_READY else None
    if match is None:
        return None
    seconds = float(match.group(3)) if match.group(3) else math.nan
    return ControllerReady(
        event.t_ns, int(match.group(1)), seconds, ControllerSource.UNKNOWN,
        match.group(2) is None, math.nan, -1,
    )  # fmt: skip


@dataclass(frozen=True, slots=True)
class RunData:
    """A recorded run, every stream as arrays.

    Attributes:
        path: The log that was read.
        info: The log's summary.
        pose: Measured poses in the arena, values (N, 3): x m, y m, psi rad.
        imu: IMU samples, values (N, 3): ax m/s^2, ay m/s^2, r rad/s.
        estimate: Observer estimate, values (N, 6): x m, y m, psi rad, u m/s, v m/s, r rad/s.
        reference: Velocity reference nu_ref, values (N, 3): u m/s, v m/s, r rad/s.
        force: Force demand tau, values (N, 3): X N, Y N, N N m.
        thrusters: Thruster commands, values (N, 5): tunnel, port, starboard in [-1, 1],
            port and starboard azimuth angles in rad.
        decisions: The symbolic controller's decisions, in time order.
        layouts: The obstacle layouts (recorded when they change), in time order.
        events: Runtime events and faults, in time order.
        repairs: What the loader left out or reordered, per topic and kind.
        skipped: Every message that did not decode and was left out.
        lab_only: The bag holds only the lab's topics (no ``/hil/...`` topic, no hil
            metadata): recorded on the tank by the lab's stack, not by hil, so it
            has no decisions, layouts or events to compare with.
        notes: What the loader assumed for a lab bag (the pose transform, log times
            for unstamped messages), one line each.
        qtm: The QTM 6D frames as received (``/hil/qtm/6d``; runs with the qtm pose
            backend), in time order.
        lab_frame: The lab's pose frame and transform from ``/tf_static`` (hil format
            3); None when the log has none.
    """

    path: Path
    info: BagInfo
    pose: Series
    imu: Series
    estimate: Series
    reference: Series
    force: Series
    thrusters: Series
    decisions: tuple[Decision, ...]
    layouts: tuple[Layout, ...]
    events: tuple[Event, ...]
    controllers: tuple[ControllerReady, ...] = ()
    repairs: tuple[Repair, ...] = ()
    skipped: tuple[SkippedMessage, ...] = ()
    lab_only: bool = False
    notes: tuple[str, ...] = ()
    qtm: tuple[QtmSample, ...] = ()
    lab_frame: LabFrame | None = None

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

    @property
    def last_stamp_ns(self) -> int:
        """Return the latest stamp (ns) of the sensors, estimates, commands and decisions.

        0 when there is none. A truncated log ends there.
        """
        streams = (self.pose, self.imu, self.estimate, self.thrusters)
        ends = [int(s.t_ns.max()) for s in streams if len(s)]
        ends += [d.t_ns for d in self.decisions[-1:]]
        return max(ends, default=0)

    @property
    def warnings(self) -> tuple[str, ...]:
        """Return one line per oddity of the log: damaged files, undecodable topics, repairs."""
        return (
            *(f"bag: {p}" for p in self.info.problems),
            *(
                f"{t.name}: cannot be decoded: {t.problem}"
                for t in self.info.topics
                if not t.decodable and t.name in topics.HIL_TOPICS
            ),
            *(str(r) for r in self.repairs),
        )

    def require_motion(self) -> RunData:
        """Return self if the run has poses or estimates to draw.

        Raises:
            NotAHilRunError: The run holds neither.
        """
        if not len(self.pose) and not len(self.estimate):
            raise NotAHilRunError(
                f"{str(self.path)!r} holds no pose and no state estimate "
                f"({topics.POSE!r}, {topics.ODOM!r}): nothing to show"
            )
        return self

    def tracking_error(self) -> TrackingSeries:
        """Return the estimated velocity's tracking error against the recorded reference.

        The one definition (:func:`hil.core.tracking.tracking_error`): each estimate
        against the reference in force at its time, in SI, ``nu_hat - nu_ref``.
        """
        return tracking_error(
            self.estimate.t_ns,
            self.estimate.values[:, 3:6],
            self.reference.t_ns,
            self.reference.values,
        )

    def controllers_ready(self) -> tuple[ControllerReady, ...]:
        """Return every controller the runtime took (early and full), in log order.

        From ``/hil/controllers``; in logs written before it, read from the
        ``controller_ready`` events (:func:`legacy_controller_ready`).
        """
        if self.controllers:
            return self.controllers
        legacy = (legacy_controller_ready(event) for event in self.events)
        return tuple(c for c in legacy if c is not None)

    def synthesis_times(self) -> tuple[ControllerReady, ...]:
        """Return each full controller whose solve time was kept (finite ``seconds``)."""
        return tuple(
            c for c in self.controllers_ready() if c.complete and math.isfinite(c.seconds)
        )

    def layout_in_force(self, t_ns: int) -> Layout | None:
        """Return the newest layout observed at or before `t_ns`; None before the first.

        The rule of :func:`hil.core.timeline.in_force` over the layouts (in time order).
        """
        k = int(in_force([layout.t_ns for layout in self.layouts], t_ns)[0])
        return self.layouts[k] if k >= 0 else None

    def layout_at(self, t_ns: int) -> Layout | None:
        """Return the layout in force at `t_ns` (else the first, or None without any)."""
        return self.layout_in_force(t_ns) or (self.layouts[0] if self.layouts else None)


_T = TypeVar("_T")


def _polygon(msg: Any) -> FloatArray:
    xs = np.asarray(msg.x, dtype=np.float64).reshape(-1)
    ys = np.asarray(msg.y, dtype=np.float64).reshape(-1)
    if xs.shape != ys.shape or xs.size < 3 or not np.all(np.isfinite(xs) & np.isfinite(ys)):
        raise ValueError(f"obstacle polygon {msg.name!r} has x={xs.tolist()!r}, y={ys.tolist()!r}")
    return np.column_stack([xs, ys])


class _Loader:
    """One pass over a bag: decode, skip bad messages, apply the rule."""

    def __init__(self, reader: BagReader, lab: LabTopics | None = None) -> None:
        self.reader = reader
        self.lab = lab
        self.skipped: list[SkippedMessage] = []
        self.repairs: list[Repair] = []
        self.notes: list[str] = []

    def unstamped(self, topic: str, raws: list[RawMessage]) -> tuple[IntArray, FloatArray]:
        """Decode a topic of Twist or Wrench messages at their log times (N,), values (N, 3)."""
        if not raws:
            return np.zeros(0, np.int64), np.zeros((0, 3))
        t_ns, values, bad = unstamped_values(raws, self.reader.decode, raws[0].msgtype)
        self._bad(topic, [SkippedMessage(raw.topic, raw.t_ns, why) for raw, why in bad])
        return t_ns, values

    def _tidied(self, topic: str, t_ns: IntArray, values: FloatArray) -> Series:
        keep = tidy(
            topic,
            t_ns,
            lambda i, j: bool(np.array_equal(values[i], values[j])),
            self.repairs,
            report_ties=True,
        )
        if len(keep) == len(t_ns) and not np.any(keep[1:] < keep[:-1]):
            return Series(t_ns, values)
        return Series(t_ns[keep], values[keep])

    def _to_arena(self, topic: str, values: FloatArray, lab: LabTopics) -> FloatArray:
        """Map the pose columns (x, y, yaw first) of a ``world_ned`` stream to the arena."""
        out = values.copy()
        if lab.pose_to_arena is not None:
            out[:, :3] = lab.pose_to_arena(values[:, :3])
        note = f"{topic}: poses in {LAB_POSE_FRAME!r} mapped to the arena"
        if lab.transform_note:
            note += f" ({lab.transform_note})"
        self.notes.append(note)
        return out

    def _bad(self, topic: str, skipped: Sequence[SkippedMessage]) -> None:
        if skipped:
            first = skipped[0]
            reason = (first.reason.splitlines() or [""])[0]
            self.repairs.append(Repair(topic, RepairKind.BAD, len(skipped), first.t_ns, reason))
            self.skipped.extend(skipped)

    def _decoded(
        self, topic: str, raws: list[RawMessage], decode: Callable[[RawMessage], _T]
    ) -> list[_T]:
        out: list[_T] = []
        skipped: list[SkippedMessage] = []
        for raw in raws:
            try:
                out.append(decode(raw))
            except ValueError as err:  # BagError, SampleError and RecordValueError all are
                skipped.append(SkippedMessage(raw.topic, raw.t_ns, str(err)))
        self._bad(topic, skipped)
        return out

    def series(self, topic: str, raws: list[RawMessage]) -> Series:
        names = FIELDS[topic]
        if not raws:
            return Series.empty(len(names))
        if raws[0].msgtype in UNSTAMPED_TYPES and len(names) == 3:
            t_ns, values = self.unstamped(topic, raws)
            self.notes.append(f"{topic}: {raws[0].msgtype} has no stamp; its log time is used")
            return self._tidied(topic, t_ns, values) if len(t_ns) else Series.empty(3)
        skipped: list[SkippedMessage] = []

        def sample(raw: RawMessage) -> Record | None:
            try:
                return self.reader.sample(raw)
            except ValueError as err:
                skipped.append(SkippedMessage(raw.topic, raw.t_ns, str(err)))
                return None

        try:
            columns = to_columns(topic, raws[0].msgtype, raws, sample)
        except BagError as err:  # one topic in several frames
            raise FrameError(f"{str(self.reader.path)!r}: {err}") from err
        self._bad(topic, skipped)
        lab_frame = (
            columns.frame_id == LAB_POSE_FRAME
            and self.lab is not None
            and self.lab.pose_to_arena is not None
        )
        if (
            topic == topics.POSE
            and columns.frame_id not in _POSE_FRAMES
            and len(columns.t_ns)
            and not lab_frame
        ):
            raise FrameError(
                f"{str(self.reader.path)!r}: poses are in frame {columns.frame_id!r}; "
                f"hil reads arena-frame poses ({topics.ARENA_FRAME!r})"
                + (f" or the lab's ({LAB_POSE_FRAME!r})" if self.lab is not None else "")
            )
        if not len(columns.t_ns):
            return Series.empty(len(names))
        values = columns.stack(*names)
        if lab_frame and self.lab is not None and topic in (topics.POSE, topics.ODOM):
            values = self._to_arena(topic, values, self.lab)
        return self._tidied(topic, columns.t_ns, values)

    def records(
        self,
        topic: str,
        raws: list[RawMessage],
        decode: Callable[[RawMessage], _T],
        key: Callable[[_T], tuple[int, object]],
    ) -> tuple[_T, ...]:
        """Decode a record topic; `key` gives (stamp, what makes two records the same)."""
        items = self._decoded(topic, raws, decode)
        keys = [key(x) for x in items]
        t_ns = np.array([k[0] for k in keys], dtype=np.int64)
        keep = tidy(topic, t_ns, lambda i, j: keys[i] == keys[j], self.repairs, report_ties=False)
        return tuple(items[int(k)] for k in keep)

    def record(self, raw: RawMessage) -> Record:
        record = self.reader.sample(raw)
        if record is None:
            raise ValueError(f"{raw.msgtype!r} on {raw.topic!r} has no record")
        return record

    def lab_frame(self, raws: list[RawMessage]) -> LabFrame | None:
        """Return the first /tf_static message's lab frame (None: none, or not hil's pair)."""
        frames = self._decoded(
            topics.TF_STATIC, raws, lambda raw: lab_frame_from_tf(self.reader.decode(raw))
        )
        return next((f for f in frames if f is not None), None)

    def layout(self, raw: RawMessage) -> Layout:
        msg = self.reader.decode(raw)
        record = to_record(raw.msgtype, msg)
        if not isinstance(record, ObstacleLayout):
            raise ValueError(f"{raw.msgtype!r} on {raw.topic!r} is not an obstacle layout")
        real = tuple(_polygon(p) for p in msg.real)
        inflated = tuple(_polygon(p) for p in msg.inflated)
        return Layout(record.t_ns, real, inflated, record.obstacles)


def _record_key(record: Record) -> tuple[int, object]:
    return record.t_ns, record


def _layout_key(layout: Layout) -> tuple[int, object]:
    return layout.t_ns, layout.rectangles


def _require_current_format(path: str | Path, custom: Mapping[str, str]) -> None:
    """Refuse a log of hil format 1 (decisions without the reference in force)."""
    if custom.get("hil_format") == "1":
        raise OldLogFormatError(
            f"{str(path)!r} is a hil log of format 1, recorded before the reference-aware "
            "symbolic controller (its decisions lack the reference in force): it cannot be "
            "judged and must be re-recorded"
        )


def _lab_only(info: BagInfo) -> bool:
    """Whether the bag holds none of hil's own topics (``/hil/...``) and no hil metadata."""
    own = {topics.THRUSTERS, *RECORD_TOPICS}
    return info.run is None and not any(t.name in own for t in info.topics)


def _require_streams(reader: BagReader, lab: LabTopics | None) -> None:
    """Raise unless the bag holds hil's topics, or (with `lab`) one of the lab's."""
    if lab is None:
        reader.require_hil_run()
        return
    present = {t.name for t in reader.info.topics}
    if not present & (set(lab.renames()) | topics.HIL_TOPICS):
        names = sorted(present)[:5]
        raise NotAHilRunError(
            f"{str(reader.path)!r} is not a hil run: none of hil's topics "
            f"(e.g. {topics.DECISION!r}) and none of the lab's (e.g. {lab.pose!r}, "
            f"{lab.imu!r}); it has {names!r}"
        )


def _stream_sources(
    present: Sequence[str], renames: Mapping[str, str]
) -> dict[str, str]:
    """Return bag topic -> the stream it is read as (see the module docstring).

    `present`: the bag's decodable topics; `renames`: the lab's topic names (a vessel
    config's) -> the stream. A stream that one of hil's own topics holds (hil format 3)
    is read from there only.
    """
    source = {name: renames.get(name, name) for name in present}
    own = {topics.STREAM_TOPICS[name] for name in present if name in topics.STREAM_TOPICS}
    out = {}
    for name, stream in source.items():
        if name in topics.STREAM_TOPICS:
            out[name] = topics.STREAM_TOPICS[name]
        elif stream not in own:
            out[name] = stream
    return out


def load_run(path: str | Path, lab: LabTopics | None = None) -> RunData:
    """Read a recorded run (see the module docstring for the rule on imperfect input).

    Args:
        path: Bag directory or ``.mcap`` file written by hil's recorder, or (with
            `lab`) recorded by the lab's stack on its own topics.
        lab: Where the lab's streams are and how its poses map to the arena
            (:mod:`hil.bag.lab_streams`); None reads hil's topics only and refuses
            poses outside the arena frame.

    Returns:
        The run's streams as arrays, with what was repaired.

    Raises:
        BagNotFoundError: The path does not exist.
        BagFormatError: Not a readable bag (truncated beyond use, foreign storage, ...).
        NotAHilRunError: A valid log without hil's topics (or the lab's, with `lab`).
        FrameError: Poses not in the arena frame (nor in the lab's, with a mapping),
            or a stream in several frames.
        OldLogFormatError: A log of hil format 1 (before the reference-aware controller).
    """
    renames = lab.renames() if lab is not None else {}
    with BagReader(path) as reader:
        _require_streams(reader, lab)
        info = reader.info
        _require_current_format(path, info.custom)
        read = (*FIELDS, *RECORD_TOPICS, *WRENCH_TOPICS, topics.QTM_6D, topics.TF_STATIC)
        by_topic: dict[str, list[RawMessage]] = {name: [] for name in read}
        # A bag topic is read as hil's stream it holds (format 3), else as the lab's
        # stream it names (the config's names), else as hil's of the same name; the
        # per-thruster commands only without hil's copy.
        source = _stream_sources([t.name for t in info.topics if t.decodable], renames)
        skip = set(WRENCH_TOPICS) if topics.THRUSTERS in source.values() else set()
        wanted = [n for n, stream in source.items() if stream in by_topic and stream not in skip]
        for raw in reader.messages(wanted):  # one pass over the chunks
            by_topic[source[raw.topic]].append(raw)
        loader = _Loader(reader, lab)
        series = {topic: loader.series(topic, by_topic[topic]) for topic in FIELDS}
        if not len(series[topics.THRUSTERS]) and any(by_topic[t] for t in WRENCH_TOPICS):
            wrenches = [loader.unstamped(t, by_topic[t]) for t in WRENCH_TOPICS]
            t_ns, values = thrusters_from_wrenches(*wrenches)
            series[topics.THRUSTERS] = Series(t_ns, values)
            loader.notes.append(
                "thruster commands read from the lab's per-thruster Wrench topics at their "
                "log times (azimuths as magnitude and angle)"
            )
        decisions = loader.records(
            topics.DECISION, by_topic[topics.DECISION], loader.record, _record_key
        )
        layouts = loader.records(
            topics.OBSTACLES, by_topic[topics.OBSTACLES], loader.layout, _layout_key
        )
        events = loader.records(topics.EVENTS, by_topic[topics.EVENTS], loader.record, _record_key)
        ready = loader.records(
            topics.CONTROLLERS, by_topic[topics.CONTROLLERS], loader.record, _record_key
        )
        qtm = loader.records(topics.QTM_6D, by_topic[topics.QTM_6D], loader.record, _record_key)
        lab_frame = loader.lab_frame(by_topic[topics.TF_STATIC])
    return RunData(
        path=Path(path),
        info=info,
        pose=series[topics.POSE],
        imu=series[topics.IMU],
        estimate=series[topics.ODOM],
        reference=series[topics.VELOCITY_COMMAND],
        force=series[topics.FORCE_COMMAND],
        thrusters=series[topics.THRUSTERS],
        decisions=tuple(r for r in decisions if isinstance(r, Decision)),
        layouts=layouts,
        events=tuple(r for r in events if isinstance(r, Event)),
        controllers=tuple(r for r in ready if isinstance(r, ControllerReady)),
        repairs=tuple(loader.repairs),
        skipped=tuple(loader.skipped),
        lab_only=_lab_only(info),
        notes=tuple(loader.notes),
        qtm=tuple(r for r in qtm if isinstance(r, QtmSample)),
        lab_frame=lab_frame,
    )
