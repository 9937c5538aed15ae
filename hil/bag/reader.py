"""Read any rosbag2 bag or bare MCAP file, hil's or foreign, without ever modifying it.

:class:`BagReader` opens a bag directory (``metadata.yaml`` plus splits, MCAP or
sqlite3) or a bare ``.mcap``/``.db3`` file, describes it (:class:`BagInfo`) and
yields its messages in log-time order: raw, decoded (rosbags message objects),
or as hil samples and records (:mod:`hil.bag.decoding`).

What happens with damaged or foreign input:

- missing path, no ``metadata.yaml``, a file that is neither MCAP nor sqlite3, a
  split listed but absent: :class:`~hil.bag.errors.BagNotFoundError` or
  :class:`~hil.bag.errors.BagFormatError` at open;
- an MCAP file that ends early (a killed recorder): every complete chunk is read,
  the rest reported in :attr:`BagInfo.problems`; the recorder's unfinished split
  (present in the directory, not yet in ``metadata.yaml``) is read the same way;
- a topic whose schema cannot be parsed, a non-ROS 2 profile, a non-CDR encoding:
  the topic is described (``decodable=False`` and the reason) and decoding it
  raises :class:`~hil.bag.errors.SchemaError` or
  :class:`~hil.bag.errors.UnsupportedBagError`;
- a payload that does not decode (a flipped bit), or decodes to a value a sample
  refuses (NaN): :class:`~hil.bag.errors.MessageDecodeError` naming the file,
  topic, index and time, or with ``on_error="skip"`` the message is skipped and
  listed in :attr:`BagReader.skipped`;
- a log without any of hil's topics: :meth:`BagReader.require_hil_run` raises
  :class:`~hil.bag.errors.NotAHilRunError` (describing it still works).
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Collection, Iterator
from dataclasses import dataclass, field
from pathlib import Path, PurePath
from typing import Any, Literal, TypeVar

from rosbags.typesys.store import Typestore

from hil.bag import topics as hil_topics
from hil.bag.decoding import FAST_DECODERS, SAMPLE_TYPES, to_record
from hil.bag.errors import (
    BagError,
    BagFormatError,
    BagNotFoundError,
    MessageDecodeError,
    NotAHilRunError,
    ReplayError,
    SchemaError,
    UnsupportedBagError,
)
from hil.bag.messages import Record
from hil.bag.metadata import METADATA_FILE, read_metadata
from hil.bag.run_info import RunInfo
from hil.bag.storage import (
    STORAGE_PLUGINS,
    FileScan,
    McapFile,
    RawMessage,
    Sqlite3File,
    storage_for,
)
from hil.bag.typestore import (
    PACKAGE,
    jazzy_typestore,
    parse_schema,
    register_hil_types,
    register_new,
)
from hil.core.lifecycle import OpenedByWith

OnError = Literal["raise", "skip"]

_T = TypeVar("_T")


@dataclass(frozen=True, slots=True)
class TopicInfo:
    """One topic of a bag.

    Attributes:
        name: Topic name.
        msgtype: Message type name.
        message_count: Complete messages on the topic (over all files).
        encoding: Message encoding (``"cdr"`` for ROS 2).
        decodable: Whether hil can decode its messages.
        problem: Why it cannot ("" when decodable).
    """

    name: str
    msgtype: str
    message_count: int
    encoding: str
    decodable: bool
    problem: str = ""


@dataclass(frozen=True, slots=True)
class BagInfo:
    """Summary of a bag.

    Attributes:
        path: The bag directory or file.
        storage: ``"mcap"`` or ``"sqlite3"``.
        files: Storage files read, in order (recorder's unfinished split last).
        topics: Topics, sorted by name.
        start_ns: Earliest log time (ns); None without messages.
        end_ns: Latest log time (ns); None without messages.
        custom: ``custom_data`` of ``metadata.yaml`` (empty for a bare file).
        problems: One line per file read only partly, or per oddity noticed.
    """

    path: Path
    storage: str
    files: tuple[str, ...]
    topics: tuple[TopicInfo, ...]
    start_ns: int | None
    end_ns: int | None
    custom: dict[str, str] = field(default_factory=dict)
    problems: tuple[str, ...] = ()

    @property
    def message_count(self) -> int:
        """Complete messages in the bag."""
        return sum(t.message_count for t in self.topics)

    @property
    def duration_ns(self) -> int:
        """Time from the first to the last message (ns); 0 without messages."""
        if self.start_ns is None or self.end_ns is None:
            return 0
        return self.end_ns - self.start_ns

    @property
    def run(self) -> RunInfo | None:
        """The run description hil stored, or None for a foreign bag."""
        return RunInfo.from_custom_data(self.custom)

    @property
    def hil_topics(self) -> tuple[str, ...]:
        """Hil's topics present in the bag."""
        return tuple(t.name for t in self.topics if t.name in hil_topics.HIL_TOPICS)

    @property
    def is_hil_run(self) -> bool:
        """Whether the bag holds any of hil's topics."""
        return bool(self.hil_topics)

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dictionary."""
        return {
            "path": str(self.path),
            "storage": self.storage,
            "files": list(self.files),
            "message_count": self.message_count,
            "start_ns": self.start_ns,
            "end_ns": self.end_ns,
            "duration_s": self.duration_ns / 1e9,
            "hil_run": self.is_hil_run,
            "custom": dict(self.custom),
            "problems": list(self.problems),
            "topics": [
                {
                    "name": t.name,
                    "type": t.msgtype,
                    "count": t.message_count,
                    "encoding": t.encoding,
                    "decodable": t.decodable,
                    "problem": t.problem,
                }
                for t in self.topics
            ],
        }


@dataclass(frozen=True, slots=True)
class SkippedMessage:
    """A message skipped with ``on_error="skip"``.

    Attributes:
        topic: Its topic.
        t_ns: Its log time (ns).
        reason: Why it was skipped.
    """

    topic: str
    t_ns: int
    reason: str


def _check_exists(path: Path) -> None:
    if not path.exists():
        raise BagNotFoundError(f"{str(path)!r} does not exist")


class BagReader(OpenedByWith):
    """Read a bag directory or a bare MCAP/sqlite3 file; never modifies it.

    Args:
        path: Bag directory (with ``metadata.yaml``) or a ``.mcap``/``.db3`` file.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.skipped: list[SkippedMessage] = []
        self._files: list[McapFile | Sqlite3File] | None = None
        self._info: BagInfo | None = None
        self._store: Typestore | None = None
        self._problems: dict[str, tuple[type[BagError], str]] = {}

    # ------------------------------------------------------------ lifecycle

    def open(self) -> None:
        """Check the path and read every file's summary.

        Raises:
            BagNotFoundError: The path does not exist.
            BagFormatError: Not a bag, or a listed split is missing or unreadable.
            UnsupportedBagError: A bag layout hil cannot read (compressed files, unknown storage).
        """
        _check_exists(self.path)
        self._problems = {}
        self.skipped = []
        if self.path.is_dir():
            storage, files, custom, problems = self._open_dir()
        else:
            backend = storage_for(self.path)
            storage = "mcap" if isinstance(backend, McapFile) else "sqlite3"
            files, custom, problems = [backend], {}, []
        scans = [f.scan() for f in files]
        self._store = jazzy_typestore(ch.msgtype for scan in scans for ch in scan.channels)
        self._files = files
        self._info = self._summarize(storage, scans, custom, problems)

    def _open_dir(
        self,
    ) -> tuple[str, list[McapFile | Sqlite3File], dict[str, str], list[str]]:
        meta_path = self.path / METADATA_FILE
        if not meta_path.is_file():
            found = sorted(p.name for p in self.path.iterdir() if p.suffix in {".mcap", ".db3"})
            hint = (
                f"; it holds {found!r}: open one file directly, or run `ros2 bag reindex`"
                if found
                else ""
            )
            raise BagFormatError(
                f"{str(self.path)!r} is not a rosbag2 bag: no {METADATA_FILE}{hint}"
            )
        meta = read_metadata(meta_path)
        storage = str(meta.get("storage_identifier", ""))
        plugin = STORAGE_PLUGINS.get(storage)
        if plugin is None:
            raise UnsupportedBagError(
                f"{str(meta_path)!r}: storage {storage!r} is not one of {sorted(STORAGE_PLUGINS)!r}"
            )
        if meta.get("compression_mode"):
            raise UnsupportedBagError(
                f"{str(meta_path)!r}: compressed bags ({meta.get('compression_mode')!r} "
                f"{meta.get('compression_format')!r}) are not supported; "
                "run `ros2 bag convert` to decompress"
            )
        names = meta.get("relative_file_paths") or []
        if not isinstance(names, list):
            raise BagFormatError(
                f"{str(meta_path)!r}: relative_file_paths is not a list: {names!r}"
            )
        listed = [self.path / PurePath(str(n)).name for n in names]
        for file_path in listed:
            if not file_path.is_file():
                raise BagFormatError(
                    f"{str(meta_path)!r} lists {file_path.name!r}, "
                    f"but {str(file_path)!r} does not exist"
                )
        # The recorder's split in progress is in the directory before it is listed.
        unlisted = sorted(
            p for p in self.path.glob("*.mcap") if p not in listed and storage == "mcap"
        )
        problems = [f"{p.name}: not listed in {METADATA_FILE} (unfinished split)" for p in unlisted]
        custom_raw = meta.get("custom_data") or {}
        custom = (
            {str(k): str(v) for k, v in custom_raw.items()} if isinstance(custom_raw, dict) else {}
        )
        files: list[McapFile | Sqlite3File] = [plugin(p) for p in [*listed, *unlisted]]
        return storage, files, custom, problems

    def _summarize(
        self, storage: str, scans: list[FileScan], custom: dict[str, str], problems: list[str]
    ) -> BagInfo:
        counts: dict[str, int] = {}
        first: dict[str, tuple[str, str, str, str]] = {}
        for scan in scans:
            if scan.problem:
                problems.append(f"{scan.path.name}: {scan.problem}")
            for ch in scan.channels:
                counts[ch.topic] = counts.get(ch.topic, 0) + ch.message_count
                if ch.topic not in first:
                    first[ch.topic] = (ch.msgtype, ch.encoding, ch.schema_encoding, ch.schema)
                    problem = self._register(
                        scan.profile, ch.msgtype, ch.encoding, ch.schema_encoding, ch.schema
                    )
                    if problem is not None:
                        self._problems[ch.topic] = problem
        topics = tuple(
            TopicInfo(
                name,
                first[name][0],
                counts[name],
                first[name][1],
                name not in self._problems,
                self._problems[name][1] if name in self._problems else "",
            )
            for name in sorted(first)
        )
        starts = [s.start_ns for s in scans if s.start_ns is not None]
        ends = [s.end_ns for s in scans if s.end_ns is not None]
        return BagInfo(
            self.path,
            storage,
            tuple(s.path.name for s in scans),
            topics,
            min(starts, default=None),
            max(ends, default=None),
            custom,
            tuple(problems),
        )

    def _register(
        self, profile: str, msgtype: str, encoding: str, schema_encoding: str, schema: str
    ) -> tuple[type[BagError], str] | None:
        """Make `msgtype` decodable; return the error class and reason if it cannot be."""
        store = self._store
        assert store is not None
        if profile != "ros2":
            return UnsupportedBagError, f"MCAP profile {profile!r} is not 'ros2'"
        if encoding != "cdr":
            return UnsupportedBagError, f"message encoding {encoding!r} is not 'cdr'"
        if schema_encoding in {"ros2msg", "ros2idl"}:
            hint = " (service schemas are not supported)" if "/srv/" in msgtype else ""
            try:
                register_new(store, parse_schema(schema_encoding, schema, msgtype))
            except SchemaError as err:
                return SchemaError, f"schema of {msgtype!r} cannot be used{hint}: {err}"
            return None
        if schema_encoding:
            return (
                UnsupportedBagError,
                f"schema encoding {schema_encoding!r} is not ros2msg or ros2idl",
            )
        if msgtype.startswith(f"{PACKAGE}/") and msgtype not in store.fielddefs:
            register_hil_types(store)
        if msgtype not in store.fielddefs:
            return (
                SchemaError,
                f"type {msgtype!r} has no schema in the bag and is not a ROS 2 Jazzy type",
            )
        return None

    def close(self) -> None:
        """Release the reader (files are opened per iteration, so this only resets state)."""
        self._files = None
        self._info = None
        self._store = None

    def _check_open(self) -> tuple[list[McapFile | Sqlite3File], BagInfo, Typestore]:
        if self._files is None or self._info is None or self._store is None:
            raise ReplayError(f"reader for {str(self.path)!r} is not open")
        return self._files, self._info, self._store

    # ------------------------------------------------------------ reading

    @property
    def info(self) -> BagInfo:
        """Summary of the bag."""
        return self._check_open()[1]

    def require_hil_run(self) -> None:
        """Raise unless the bag holds hil's topics.

        Raises:
            NotAHilRunError: None of hil's topics is in the bag.
        """
        info = self.info
        if not info.is_hil_run:
            names = [t.name for t in info.topics][:5]
            raise NotAHilRunError(
                f"{str(self.path)!r} is not a hil run: none of hil's topics "
                f"(e.g. {hil_topics.POSE!r}, {hil_topics.DECISION!r}); it has {names!r}"
            )

    def messages(self, topics: Collection[str] | None = None) -> Iterator[RawMessage]:
        """Yield raw messages on `topics` (all when None) in log-time order over all files.

        Raises:
            BagFormatError: A file cannot be read where its summary said it could.
        """
        files, _, _ = self._check_open()
        wanted = None if topics is None else frozenset(topics)
        streams = [f.messages(wanted) for f in files]
        if len(streams) == 1:
            yield from streams[0]
        else:
            yield from heapq.merge(*streams, key=lambda m: m.t_ns)

    def decode(self, raw: RawMessage) -> Any:
        """Decode one raw message into a rosbags message object.

        Raises:
            SchemaError: The topic's type cannot be decoded (see :attr:`TopicInfo.problem`).
            UnsupportedBagError: The topic is not ROS 2 CDR.
            MessageDecodeError: The payload does not decode.
        """
        _, _, store = self._check_open()
        problem = self._problems.get(raw.topic)
        if problem is not None:
            cls, reason = problem
            raise cls(f"{str(self.path)!r}: topic {raw.topic!r} cannot be decoded: {reason}")
        try:
            return store.deserialize_cdr(raw.data, raw.msgtype)
        except Exception as err:
            raise MessageDecodeError(
                f"{str(self.path)!r}: message on {raw.topic!r} at t={raw.t_ns} ns "
                f"({raw.msgtype}, {len(raw.data)} bytes) does not decode: "
                f"{type(err).__name__}: {err}"
            ) from err

    def decoded(
        self, topics: Collection[str] | None = None, *, on_error: OnError = "raise"
    ) -> Iterator[tuple[str, int, Any]]:
        """Yield ``(topic, t_ns, message)`` in log-time order.

        Args:
            topics: Topics to read; all when None.
            on_error: ``"raise"`` on the first bad message, or ``"skip"`` it and
                list it in :attr:`skipped`.

        Raises:
            BagError: A message or topic cannot be decoded and `on_error` is "raise".
        """
        for raw, msg in self._converted(topics, on_error, self.decode):
            yield raw.topic, raw.t_ns, msg

    def _converted(
        self,
        topics: Collection[str] | None,
        on_error: OnError,
        convert: Callable[[RawMessage], _T],
    ) -> Iterator[tuple[RawMessage, _T]]:
        """Yield each message of `topics` with `convert`'s result, in log-time order.

        A message `convert` refuses (:class:`BagError`) raises, or with ``"skip"`` is
        listed in :attr:`skipped` and left out.
        """
        for raw in self.messages(topics):
            try:
                out = convert(raw)
            except BagError as err:
                if on_error == "raise":
                    raise
                self.skipped.append(SkippedMessage(raw.topic, raw.t_ns, str(err)))
                continue
            yield raw, out

    def records(
        self, topics: Collection[str] | None = None, *, on_error: OnError = "raise"
    ) -> Iterator[tuple[str, int, Record]]:
        """Yield ``(topic, t_ns, sample or record)`` for hil's topics, in log-time order.

        Args:
            topics: Topics to read; default every topic whose type has a sample
                (:data:`hil.bag.decoding.SAMPLE_TYPES`), a stream's lab topic left out
                where hil's own copy is there (hil format 3: the records hil recorded,
                once each; the lab's pose as received is read by naming its topic).
            on_error: As in :meth:`decoded`; also covers values a sample refuses (NaN).

        Raises:
            NotAHilRunError: The bag holds none of hil's topics.
            MessageDecodeError: A message is bad and `on_error` is "raise".
        """
        self.require_hil_run()
        info = self.info
        if topics is None:
            present = {t.name for t in info.topics}
            copied = {
                lab for lab, own in hil_topics.STREAM_TOPICS_BY_STREAM.items() if own in present
            }
            topics = [
                t.name for t in info.topics if t.msgtype in SAMPLE_TYPES and t.name not in copied
            ]
        for raw, record in self._converted(topics, on_error, self.sample):
            if record is not None:
                yield raw.topic, raw.t_ns, record

    def sample(self, raw: RawMessage) -> Record | None:
        """Convert one raw message to a sample or record; None for types without one.

        Fixed-layout types are unpacked straight from the CDR payload
        (:data:`hil.bag.decoding.FAST_DECODERS`), others decoded with rosbags.

        Raises:
            MessageDecodeError: The payload does not decode, or holds a value a
                sample refuses (NaN, unknown frame).
            SchemaError: The topic's type cannot be decoded.
        """
        try:
            fast = FAST_DECODERS.get(raw.msgtype)
            record = fast(raw.data) if fast is not None else None
            if record is None:
                record = to_record(raw.msgtype, self.decode(raw))
        except ValueError as err:
            if isinstance(err, BagError):
                raise
            raise MessageDecodeError(
                f"{str(self.path)!r}: message on {raw.topic!r} at t={raw.t_ns} ns is not a "
                f"valid sample: {err}"
            ) from err
        return record


def describe(path: str | Path) -> BagInfo:
    """Return the summary of the bag at `path` (see :class:`BagReader`)."""
    with BagReader(path) as reader:
        return reader.info
