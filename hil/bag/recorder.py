"""Crash-safe recorder: every sample, command, decision and event to a rosbag2 MCAP bag.

Design (each choice answers "what is left after SIGKILL?"):

- The caller's thread only checks a record (type and time; samples and records
  refuse NaN when built) and appends it to a deque: well under a microsecond,
  so the loop is not slowed and a bad record raises before anything is written.
- Every ``flush_s`` (0.5 s) of wall time a background thread (or the caller's,
  with ``threaded=False``) encodes what is queued, the fixed-layout streams in
  bulk with numpy (:mod:`hil.bag.columnar`, about a microsecond a message),
  appends it to the split as one zstd chunk (:mod:`hil.bag.mcap_writer`,
  records serialized by the ``mcap`` package) and flushes the file. A killed
  process loses at most the last flush interval: the chunks already written
  are complete, and :mod:`hil.bag.recover` (or
  :class:`hil.bag.reader.BagReader` directly) reads them back.
- Every ``split_s`` seconds the writer finishes the split (summary, footer) and
  rewrites ``metadata.yaml`` atomically to list the closed splits, so rosbags,
  ``ros2 bag`` and Foxglove open the bag at any moment, up to the last split.
- ``metadata.yaml`` is written at open too, with the run's description in
  ``custom_data`` (scenario file and hash, seed, hil version, git revision).
- Each split is whole on its own, as rosbag2 writes one: it starts with ``/tf_static``
  (the lab frame -> arena and mocap body -> body transforms, at the split's first
  message time) and ends with rosbag2's ``"rosbag2"`` Metadata record (the bag's
  metadata so far), so ``ros2 bag info`` and rosbag2's MCAP plugin read it.
"""

from __future__ import annotations

import functools
import os
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Literal, Protocol

import numpy as np

from hil import __version__
from hil.bag import topics
from hil.bag import typestore as ts
from hil.bag.columnar import BULK_ENCODERS, Block, encode_poses
from hil.bag.errors import RecorderClosedError, RecorderError, RecordValueError
from hil.bag.lab_frame import LabFrame
from hil.bag.mcap_writer import McapChunkWriter
from hil.bag.messages import Encoded, Record, encode, encode_tf_static
from hil.bag.metadata import (
    RECORD_NAME,
    FileEntry,
    TopicEntry,
    rosbag2_record,
    write_metadata,
)
from hil.bag.run_info import RunInfo
from hil.core.arrays import FloatArray
from hil.core.lifecycle import OpenedByWith
from hil.core.records import (
    ControllerReady,
    Decision,
    Event,
    EventLevel,
    ForceCommand,
    StateEstimate,
)
from hil.core.samples import (
    ImuSample,
    ObstacleLayout,
    PoseSample,
    ThrusterCommand,
    VelocityReference,
)


class RecordSink(Protocol):
    """What the runtime needs of a recorder (the recorder, or a test double)."""

    def record(self, record: Record) -> None:
        """Record one sample or record; never blocks on I/O."""

    def close(self) -> None:
        """Flush everything and close the log."""


@dataclass(frozen=True, slots=True)
class RecorderConfig:
    """How the recorder writes.

    Attributes:
        split_s: Wall-clock seconds per split file (closed and listed in metadata.yaml).
        flush_s: Wall-clock seconds between flushes (what a SIGKILL can lose).
        chunk_bytes: Largest uncompressed chunk; a flush closes a chunk earlier.
        compression: Chunk compression.
        threaded: Write on a background thread (True) or inline in record().
        fsync: Also fsync at each flush (survives power loss; slower on SD cards).
    """

    split_s: float = 5.0
    flush_s: float = 0.5
    chunk_bytes: int = 1 << 20
    compression: Literal["zstd", "lz4", "none"] = "zstd"
    threaded: bool = True
    fsync: bool = False

    def __post_init__(self) -> None:
        if not self.flush_s > 0 or not self.split_s >= self.flush_s:
            raise RecordValueError(
                f"need 0 < flush_s <= split_s, got flush_s={self.flush_s!r}, "
                f"split_s={self.split_s!r}"
            )
        if self.chunk_bytes < 1024:
            raise RecordValueError(f"chunk_bytes must be >= 1024, got {self.chunk_bytes!r}")


_COMPRESSION: dict[str, Literal["zstd", "lz4", ""]] = {"zstd": "zstd", "lz4": "lz4", "none": ""}


@dataclass(slots=True)
class _Split:
    """The split being written."""

    name: str
    stream: IO[bytes]
    writer: McapChunkWriter
    opened_s: float
    channels: dict[str, int] = field(default_factory=dict)
    counts: Counter[str] = field(default_factory=Counter)
    start_ns: int = 2**63 - 1
    end_ns: int = 0


class _BagWriter:
    """Writes splits and metadata.yaml; used by one thread only."""

    def __init__(
        self, bag_dir: Path, custom: dict[str, str], config: RecorderConfig, lab: LabFrame
    ) -> None:
        self.dir = bag_dir
        self.custom = custom
        self.config = config
        self.lab = lab
        self.encoders: dict[type, Callable[[Sequence[Any]], list[Block]]] = {
            **BULK_ENCODERS,
            PoseSample: functools.partial(encode_poses, lab=lab),
        }
        self.files: list[FileEntry] = []
        self.counts: Counter[str] = Counter()
        self.split: _Split | None = None
        self.messages = 0

    def _entries(self, counts: Counter[str]) -> list[TopicEntry]:
        return [
            TopicEntry(name, topics.TOPIC_TYPES[name], count, _type_hash(topics.TOPIC_TYPES[name]))
            for name, count in sorted(counts.items())
        ]

    def write_metadata(self) -> None:
        entries = self._entries(self.counts)
        write_metadata(self.dir, self.files, entries, self.custom, fsync=self.config.fsync)

    def _split(self, now_s: float, t_ns: int) -> _Split:
        """Return the split in progress, or open one that starts with /tf_static at `t_ns`."""
        if self.split is not None:
            return self.split
        split = self._open_split(now_s)
        self.add(t_ns, encode_tf_static(t_ns, self.lab), now_s)
        return split

    def _open_split(self, now_s: float) -> _Split:
        name = f"{self.dir.name}_{len(self.files)}.mcap"
        stream = (self.dir / name).open("xb")
        writer = McapChunkWriter(
            stream,
            profile="ros2",
            library=f"hil {__version__}",
            compression=_COMPRESSION[self.config.compression],
            chunk_bytes=self.config.chunk_bytes,
        )
        self.split = _Split(name, stream, writer, now_s)
        return self.split

    def _channel(self, split: _Split, topic: str) -> int:
        msgtype = topics.TOPIC_TYPES[topic]
        schema = split.writer.register_schema(msgtype, "ros2msg", ts.schema_text(msgtype).encode())
        channel = split.writer.register_channel(
            topic,
            "cdr",
            schema,
            {"offered_qos_profiles": "", "topic_type_hash": _type_hash(msgtype)},
        )
        split.channels[topic] = channel
        return channel

    def add(self, t_ns: int, encoded: Encoded, now_s: float) -> None:
        split = self._split(now_s, t_ns)
        for topic, payload in encoded:
            channel = split.channels.get(topic)
            if channel is None:
                channel = self._channel(split, topic)
            sequence = split.counts[topic]
            split.writer.add_message(channel, t_ns, payload, sequence)
            split.counts[topic] = sequence + 1
        split.start_ns = min(split.start_ns, t_ns)
        split.end_ns = max(split.end_ns, t_ns)
        self.messages += len(encoded)

    def _add_block(self, block: Block, now_s: float) -> None:
        split = self._split(now_s, int(block.t_ns.min()))
        channel = split.channels.get(block.topic)
        if channel is None:
            channel = self._channel(split, block.topic)
        sequence = split.counts[block.topic]
        n = len(block.t_ns)
        rows = max(1, self.config.chunk_bytes // (block.payloads.shape[1] + 31))
        for first in range(0, n, rows):  # keep chunks near chunk_bytes
            last = min(n, first + rows)
            split.writer.add_block(
                channel, block.t_ns[first:last], block.payloads[first:last], sequence + first
            )
        split.counts[block.topic] = sequence + n
        split.start_ns = min(split.start_ns, int(block.t_ns.min()))
        split.end_ns = max(split.end_ns, int(block.t_ns.max()))
        self.messages += n

    def write_batch(self, batch: list[Record | tuple[int, Encoded]], now_s: float) -> None:
        """Write a batch: (time, encoded) pairs as they are, the rest in bulk per topic."""
        groups: dict[type, list[Record]] = {}
        for item in batch:
            if isinstance(item, tuple):
                self.add(item[0], item[1], now_s)
                continue
            group = groups.get(type(item))
            if group is None:
                group = groups[type(item)] = []
            group.append(item)
        for kind, records in groups.items():
            for block in self.encoders[kind](records):
                self._add_block(block, now_s)

    def tick(self, now_s: float) -> None:
        """Flush; close the split when it is older than split_s."""
        split = self.split
        if split is None:
            return
        if now_s - split.opened_s >= self.config.split_s:
            self.close_split()
            return
        split.writer.flush()
        if self.config.fsync:
            os.fsync(split.stream.fileno())

    def close_split(self) -> None:
        split, self.split = self.split, None
        if split is None:
            return
        entry = FileEntry(split.name, split.start_ns, split.end_ns, sum(split.counts.values()))
        split.writer.add_metadata(
            RECORD_NAME,
            rosbag2_record(
                [*self.files, entry], self._entries(self.counts + split.counts), self.custom
            ),
        )
        split.writer.finish()
        split.stream.flush()
        if self.config.fsync:
            os.fsync(split.stream.fileno())
        split.stream.close()
        self.files.append(entry)
        self.counts.update(split.counts)
        self.write_metadata()


@functools.cache
def _type_hash(msgtype: str) -> str:
    return str(ts.typestore().hash_rihs01(msgtype))


_MAX_T_NS = 2**31 * 1_000_000_000


class Recorder(OpenedByWith):
    """Record a run to a rosbag2 directory with MCAP splits.

    Use as a context manager, or call :meth:`open` and :meth:`close`::

        with Recorder(out / "run", RunInfo.current("paper.toml", h, seed=3)) as rec:
            rec.record(pose_sample)
            rec.record(decision)

    Args:
        path: The bag directory to create (must not exist, or be empty).
        run: What produced the run (stored as ``custom_data``).
        config: How to write.
        lab: The lab's pose frame and the transform to the arena (the vessel config's
            ``[ros.transform]`` and ``pose_frame_id``): arena poses go to the lab's pose
            topic mapped back through it, and onto ``/tf_static``. None: identity,
            ``world_ned`` (simulation without a vessel config).
    """

    def __init__(
        self,
        path: str | Path,
        run: RunInfo | None = None,
        config: RecorderConfig | None = None,
        lab: LabFrame | None = None,
    ) -> None:
        self.path = Path(path)
        self.run = run if run is not None else RunInfo()
        self.config = config if config is not None else RecorderConfig()
        self.lab = lab if lab is not None else LabFrame()
        self._bag: _BagWriter | None = None
        self._pending: deque[Record | tuple[int, Encoded]] = deque()
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._flush_requests: deque[threading.Event] = deque()
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None
        self._next_tick_s = 0.0
        self._closed = False
        self._closed_files: tuple[str, ...] = ()

    @property
    def is_open(self) -> bool:
        """Whether the recorder accepts records."""
        return self._bag is not None

    @property
    def files(self) -> tuple[str, ...]:
        """Names of the closed splits so far (read after close() for the full list)."""
        if self._bag is None:
            return self._closed_files
        return tuple(f.path for f in self._bag.files)

    def open(self) -> None:
        """Create the bag directory, write metadata.yaml, start the writer thread.

        Raises:
            RecorderError: Already open or closed, or the path is not a new/empty directory.
        """
        if self._bag is not None or self._closed:
            raise RecorderError(f"recorder for {str(self.path)!r} was already opened")
        if self.path.exists() and (not self.path.is_dir() or any(self.path.iterdir())):
            raise RecorderError(f"{str(self.path)!r} exists and is not an empty directory")
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            bag = _BagWriter(self.path, self.run.custom_data(), self.config, self.lab)
            bag.write_metadata()
        except OSError as err:
            raise RecorderError(f"cannot create bag {str(self.path)!r}: {err}") from err
        self._bag = bag
        self._next_tick_s = time.monotonic() + self.config.flush_s
        if self.config.threaded:
            self._thread = threading.Thread(
                target=self._run, name=f"hil-recorder:{self.path.name}", daemon=True
            )
            self._thread.start()

    def _check_open(self) -> _BagWriter:
        if self._bag is None:
            state = "closed" if self._closed else "not open"
            raise RecorderClosedError(f"recorder for {str(self.path)!r} is {state}")
        if self._error is not None:
            raise RecorderError(
                f"recorder for {str(self.path)!r} failed: {self._error}"
            ) from self._error
        return self._bag

    def record(self, record: Record) -> None:
        """Record one sample or record (see :data:`hil.bag.messages.Record`).

        Checks the record here, on the caller's thread, so a bad one raises before
        anything is written (samples and records refuse NaN when built); encoding
        and writing happen in batches at each flush, on the writer thread (or
        inline when ``threaded=False``). Costs well under a microsecond.

        Raises:
            RecorderClosedError: The recorder is not open.
            RecorderError: Writing failed earlier (disk full, ...).
            RecordValueError: Unknown record type, or a time that does not fit a ROS stamp.
        """
        if self._bag is None or self._error is not None:
            self._check_open()
        kind = type(record)
        if kind not in BULK_ENCODERS:
            # Rare, variable-size records (decisions, layouts, events) and unknown types
            # are encoded now, so that any error is the caller's, not the writer's.
            encoded = encode(record)  # raises the RecordValueError naming an unknown type
            self._pending.append((record.t_ns, encoded))
        else:
            t_ns = record.t_ns
            if not ((type(t_ns) is int or isinstance(t_ns, np.integer)) and 0 <= t_ns < _MAX_T_NS):
                raise RecordValueError(
                    f"{kind.__name__} time {t_ns!r} is not an integer ns in [0, 2^31 s)"
                )
            self._pending.append(record)
        if self._thread is None and time.monotonic() >= self._next_tick_s:
            self._write_pending(tick=True)

    def _write_pending(self, *, tick: bool) -> None:
        """Write what is queued, then flush (and maybe rotate the split) if `tick`."""
        bag = self._bag
        assert bag is not None
        pending = self._pending
        batch = [pending.popleft() for _ in range(len(pending))]
        now = time.monotonic()
        try:
            if batch:
                bag.write_batch(batch, now)
            if tick:
                bag.tick(now)
                self._next_tick_s = now + self.config.flush_s
        except Exception as err:
            self._error = err
            raise RecorderError(f"cannot write bag {str(self.path)!r}: {err}") from err

    def flush(self) -> None:
        """Write what is queued and flush it to disk now (the writer does so every flush_s).

        Raises:
            RecorderClosedError: The recorder is not open.
            RecorderError: Writing failed.
        """
        self._check_open()
        if self._thread is None:
            self._write_pending(tick=True)
            return
        done = threading.Event()
        self._flush_requests.append(done)
        self._wake.set()
        thread = self._thread
        while not done.wait(0.05) and thread.is_alive():
            pass
        self._check_open()

    # The runtime's RunLog interface (hil.runtime.protocols.RunLog), one method per stream.
    def pose(self, sample: PoseSample) -> None:
        """Record a pose sample as received."""
        self.record(sample)

    def imu(self, sample: ImuSample) -> None:
        """Record an IMU sample as received."""
        self.record(sample)

    def estimate(self, t_ns: int, eta: FloatArray, nu: FloatArray) -> None:
        """Record the observer's estimate: eta = (x, y, psi), nu = (u, v, r), shapes (3,)."""
        self.record(
            StateEstimate(
                t_ns,
                float(eta[0]),
                float(eta[1]),
                float(eta[2]),
                float(nu[0]),
                float(nu[1]),
                float(nu[2]),
            )
        )

    def velocity_reference(self, t_ns: int, nu_ref: FloatArray) -> None:
        """Record the velocity reference (u, v, r), shape (3,)."""
        self.record(VelocityReference(t_ns, float(nu_ref[0]), float(nu_ref[1]), float(nu_ref[2])))

    def force(self, t_ns: int, tau: FloatArray) -> None:
        """Record the generalized force (X, Y, N), shape (3,)."""
        self.record(ForceCommand(t_ns, float(tau[0]), float(tau[1]), float(tau[2])))

    def thrusters(self, command: ThrusterCommand) -> None:
        """Record a thruster command as sent."""
        self.record(command)

    def decision(self, record: Decision) -> None:
        """Record one decision of the symbolic controller."""
        self.record(record)

    def obstacles(self, layout: ObstacleLayout) -> None:
        """Record an obstacle layout."""
        self.record(layout)

    def event(self, t_ns: int, level: EventLevel, code: str, text: str) -> None:
        """Record a runtime event or fault."""
        self.record(Event(t_ns, level, code, text))

    def controller_ready(self, record: ControllerReady) -> None:
        """Record a controller taken from the re-synthesis."""
        self.record(record)

    def _run(self) -> None:
        while not self._stop.is_set():
            self._wake.wait(max(0.0, self._next_tick_s - time.monotonic()))
            self._wake.clear()
            requests = [self._flush_requests.popleft() for _ in range(len(self._flush_requests))]
            try:
                if requests or time.monotonic() >= self._next_tick_s:
                    self._write_pending(tick=True)
            except RecorderError:
                return  # reported to the caller by record(), flush() and close()
            finally:
                for done in requests:
                    done.set()

    def close(self) -> None:
        """Write everything queued, finish the last split and metadata.yaml.

        Closing twice is allowed; the second call does nothing.

        Raises:
            RecorderError: Writing failed; the splits closed before stay readable.
        """
        bag = self._bag
        if bag is None:
            return
        if self._thread is not None:
            self._stop.set()
            self._wake.set()
            self._thread.join()
            self._thread = None
        error = self._error
        if error is None:
            try:
                self._write_pending(tick=False)
            except RecorderError:
                error = self._error
        try:
            bag.close_split()
        except OSError as err:
            error = error or err
        self._bag = None
        self._closed = True
        self._closed_files = tuple(f.path for f in bag.files)
        if error is not None:
            raise RecorderError(f"recorder for {str(self.path)!r} failed: {error}") from error
