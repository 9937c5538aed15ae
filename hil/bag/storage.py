"""Read-only access to one storage file of a bag: an MCAP file or a rosbag2 sqlite3 file.

Each backend answers two questions: what is in the file (:class:`FileScan`: its
channels, counts and time range, and whether it ended early), and the raw
messages in time order. Nothing here decodes payloads or writes to the file:
MCAP files are opened ``rb``, sqlite3 files with ``mode=ro&immutable=1`` so that
not even a journal is created beside them.

An MCAP file that lacks its end magic (a killed recorder, a cut download) is read
with a streaming pass that keeps every complete record and stops at the first
incomplete or corrupt one.
"""

from __future__ import annotations

import bisect
import operator
import sqlite3
import struct
import urllib.parse
from collections.abc import Callable, Collection, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, NamedTuple, Protocol

import lz4.frame  # type: ignore[import-untyped]
import zstandard
from mcap.reader import SeekingReader
from mcap.records import Channel, ChunkIndex, Message, Schema
from mcap.stream_reader import StreamReader

from hil.bag.errors import BagFormatError

MCAP_MAGIC = b"\x89MCAP0\r\n"
_CHUNK_HEAD = struct.Struct("<QQQII")  # start, end, uncompressed size, crc, compression length
_RECORD_HEAD = struct.Struct("<BQ")  # opcode, length
_MESSAGE_HEAD = struct.Struct("<HIQ")  # channel, sequence, log time
_log_time = operator.attrgetter("t_ns")  # of a RawMessage


def _decompress(compression: str, data: bytes, size: int) -> bytes:
    if compression == "zstd":
        return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
    if compression == "lz4":
        return bytes(lz4.frame.decompress(data))
    if compression == "":
        return data
    raise ValueError(f"unknown chunk compression {compression!r}")


SQLITE_MAGIC = b"SQLite format 3\x00"


class RawMessage(NamedTuple):
    """One undecoded message.

    Attributes:
        topic: Topic name.
        t_ns: Log time (ns).
        msgtype: Full message type name.
        data: Serialized payload (CDR for ROS 2 bags).
    """

    topic: str
    t_ns: int
    msgtype: str
    data: bytes


@dataclass(frozen=True, slots=True)
class ChannelScan:
    """One channel (topic) of a file.

    Attributes:
        topic: Topic name.
        msgtype: Message type name (schema name).
        encoding: Message encoding, e.g. ``"cdr"`` or ``"protobuf"``.
        schema_encoding: Schema encoding, e.g. ``"ros2msg"``; "" when the file has none.
        schema: Schema text; "" when the file has none.
        message_count: Complete messages on the channel in the file.
        qos: The channel's ``offered_qos_profiles`` metadata (YAML text; "" if none).
    """

    topic: str
    msgtype: str
    encoding: str
    schema_encoding: str
    schema: str
    message_count: int
    qos: str = ""


@dataclass(frozen=True, slots=True)
class FileScan:
    """What one storage file holds.

    Attributes:
        path: The file.
        profile: MCAP profile (``"ros2"`` for ROS 2 bags); ``"ros2"`` for sqlite3.
        channels: Its channels.
        start_ns: Earliest log time; None without messages.
        end_ns: Latest log time; None without messages.
        problem: Why the file was read only partly ("" when read whole).
    """

    path: Path
    profile: str
    channels: tuple[ChannelScan, ...]
    start_ns: int | None
    end_ns: int | None
    problem: str = ""

    @property
    def message_count(self) -> int:
        """Complete messages in the file."""
        return sum(c.message_count for c in self.channels)


class StorageFile(Protocol):
    """A storage backend for one file."""

    def scan(self) -> FileScan:
        """Return what the file holds, reading it without modifying it."""

    def messages(self, topics: Collection[str] | None) -> Iterator[RawMessage]:
        """Yield the messages on `topics` (all when None), in log-time order."""


def _describe(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[0]}" if text else type(err).__name__


def _schema_text(schema: Schema | None) -> tuple[str, str, str]:
    if schema is None:
        return "", "", ""
    try:
        text = schema.data.decode("utf-8")
    except UnicodeDecodeError:
        text = ""
    return schema.name, schema.encoding, text


class McapFile:
    """An MCAP file, read through its summary or, if it ends early, by streaming."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._complete: bool | None = None

    def _is_complete(self) -> bool:
        """Whether the file ends with the MCAP magic (a finished writer)."""
        if self._complete is None:
            try:
                with self.path.open("rb") as stream:
                    head = stream.read(len(MCAP_MAGIC))
                    if len(head) < len(MCAP_MAGIC) and MCAP_MAGIC.startswith(head):
                        self._complete = False  # cut before or inside the magic
                        return False
                    if head != MCAP_MAGIC:
                        raise BagFormatError(
                            f"{str(self.path)!r} is not an MCAP file (starts with {head!r})"
                        )
                    size = stream.seek(0, 2)
                    stream.seek(max(0, size - len(MCAP_MAGIC)))
                    self._complete = size >= 2 * len(MCAP_MAGIC) and stream.read() == MCAP_MAGIC
            except OSError as err:
                raise BagFormatError(f"cannot read {str(self.path)!r}: {err}") from err
        return self._complete

    def scan(self) -> FileScan:
        """Return what the file holds (summary if intact, else a streaming pass)."""
        if self._is_complete():
            try:
                with self.path.open("rb") as stream:
                    reader = SeekingReader(stream)
                    header = reader.get_header()
                    summary = reader.get_summary()
            except Exception:
                summary = None
            if summary is not None and summary.statistics is not None:
                stats = summary.statistics
                channels = []
                for ch in summary.channels.values():
                    name, encoding, text = _schema_text(summary.schemas.get(ch.schema_id))
                    count = stats.channel_message_counts.get(ch.id, 0)
                    qos = ch.metadata.get("offered_qos_profiles", "")
                    channels.append(
                        ChannelScan(ch.topic, name, ch.message_encoding, encoding, text, count, qos)
                    )
                has = stats.message_count > 0
                return FileScan(
                    self.path,
                    header.profile,
                    tuple(channels),
                    stats.message_start_time if has else None,
                    stats.message_end_time if has else None,
                )
        return self._stream_scan()

    def records(self) -> Iterator[tuple[str, Any]]:
        """Yield ("header"|"schema"|"channel"|"message", record), then ("end", problem)."""
        problem = "" if self._is_complete() else "file ends early (truncated)"
        try:
            with self.path.open("rb") as stream:
                size = self.path.stat().st_size
                reader = StreamReader(stream, record_size_limit=size)
                for record in reader.records:
                    if isinstance(record, Message):
                        yield "message", record
                    elif isinstance(record, Channel):
                        yield "channel", record
                    elif isinstance(record, Schema):
                        yield "schema", record
                    elif type(record).__name__ == "Header":
                        yield "header", record
        except Exception as err:
            where = "file ends early (truncated)" if not self._is_complete() else "damaged"
            problem = f"{where}: stopped at {_describe(err)}"
        yield "end", problem

    def _stream_scan(self) -> FileScan:
        profile = ""
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        counts: dict[int, int] = {}
        start: int | None = None
        end: int | None = None
        problem = ""
        for kind, record in self.records():
            if kind == "message":
                counts[record.channel_id] = counts.get(record.channel_id, 0) + 1
                t = record.log_time
                start = t if start is None else min(start, t)
                end = t if end is None else max(end, t)
            elif kind == "channel":
                channels[record.id] = record
            elif kind == "schema":
                schemas[record.id] = record
            elif kind == "header":
                profile = record.profile
            else:
                problem = record
        scans = []
        for ch in channels.values():
            name, encoding, text = _schema_text(schemas.get(ch.schema_id))
            count = counts.get(ch.id, 0)
            qos = ch.metadata.get("offered_qos_profiles", "")
            scans.append(
                ChannelScan(ch.topic, name, ch.message_encoding, encoding, text, count, qos)
            )
        return FileScan(self.path, profile, tuple(scans), start, end, problem)

    def messages(self, topics: Collection[str] | None) -> Iterator[RawMessage]:
        """Yield messages in log-time order (ties in file order).

        Raises:
            BagFormatError: The file cannot be opened, or a chunk is damaged.
        """
        try:
            if self._is_complete():
                yield from self._seek_messages(topics)
            else:
                yield from self._stream_messages(topics)
        except OSError as err:
            raise BagFormatError(f"cannot read {str(self.path)!r}: {err}") from err

    def _seek_messages(self, topics: Collection[str] | None) -> Iterator[RawMessage]:
        """Read chunk by chunk through the summary's chunk index, merging by log time."""
        with self.path.open("rb") as stream:
            try:
                summary = SeekingReader(stream).get_summary()
            except Exception:
                summary = None
            if summary is None or not summary.chunk_indexes:
                yield from self._stream_messages(topics)
                return
            channels = {
                ch.id: (ch.topic, summary.schemas[ch.schema_id].name if ch.schema_id else "")
                for ch in summary.channels.values()
                if topics is None or ch.topic in topics
            }
            # Messages read but not yet yielded, sorted by log time (ties in file order).
            pending: list[RawMessage] = []
            for index in sorted(summary.chunk_indexes, key=lambda c: c.message_start_time):
                if index.message_index_offsets and not any(
                    cid in channels for cid in index.message_index_offsets
                ):
                    continue  # the chunk's index says it holds none of the wanted channels
                # Messages before this chunk's first time cannot come later: yield them.
                ready = bisect.bisect_left(pending, index.message_start_time, key=_log_time)
                yield from pending[:ready]
                # Stable sort of two runs (the rest, then this chunk in file order): a merge.
                pending = pending[ready:] + self._chunk_messages(stream, index, channels)
                pending.sort(key=_log_time)
            yield from pending

    def _chunk_messages(
        self, stream: IO[bytes], index: ChunkIndex, channels: dict[int, tuple[str, str]]
    ) -> list[RawMessage]:
        """Return the messages of one chunk's wanted channels, in file order."""
        try:
            stream.seek(index.chunk_start_offset + 9)  # opcode and record length
            record = stream.read(index.chunk_length - 9)
            _, _, size, _, name_len = _CHUNK_HEAD.unpack_from(record, 0)
            compression = record[32 : 32 + name_len].decode()
            (data_len,) = struct.unpack_from("<Q", record, 32 + name_len)
            start = 40 + name_len
            data = _decompress(compression, record[start : start + data_len], size)
        except (
            OSError,
            OverflowError,  # a damaged uncompressed-size field beyond what memory allows
            struct.error,
            UnicodeDecodeError,
            ValueError,
            zstandard.ZstdError,
        ) as err:
            raise BagFormatError(
                f"{str(self.path)!r}: chunk at offset {index.chunk_start_offset} cannot be read: "
                f"{_describe(err)}"
            ) from err
        view = memoryview(data)
        pos, end = 0, len(data)
        unpack = _RECORD_HEAD.unpack_from
        unpack_message = _MESSAGE_HEAD.unpack_from
        out: list[RawMessage] = []
        append = out.append
        while pos + 9 <= end:
            opcode, length = unpack(data, pos)
            body = pos + 9
            pos = body + length
            if opcode != 0x05 or pos > end:
                continue
            channel_id, _, log_time = unpack_message(data, body)
            wanted = channels.get(channel_id)
            if wanted is not None:
                append(RawMessage(wanted[0], log_time, wanted[1], bytes(view[body + 22 : pos])))
        return out

    def _stream_messages(self, topics: Collection[str] | None) -> Iterator[RawMessage]:
        schemas: dict[int, str] = {}
        channels: dict[int, tuple[str, str]] = {}
        found: list[tuple[int, int, RawMessage]] = []
        for kind, record in self.records():
            if kind == "message":
                topic, msgtype = channels.get(record.channel_id, ("", ""))
                if topics is None or topic in topics:
                    raw = RawMessage(topic, record.log_time, msgtype, record.data)
                    found.append((record.log_time, len(found), raw))
            elif kind == "channel":
                channels[record.id] = (record.topic, schemas.get(record.schema_id, ""))
            elif kind == "schema":
                schemas[record.id] = record.name
        found.sort(key=lambda item: (item[0], item[1]))
        for _, _, raw in found:
            yield raw


class Sqlite3File:
    """A rosbag2 sqlite3 (``.db3``) file, opened read-only and immutable."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def _connect(self) -> sqlite3.Connection:
        try:
            with self.path.open("rb") as stream:
                head = stream.read(len(SQLITE_MAGIC))
        except OSError as err:
            raise BagFormatError(f"cannot read {str(self.path)!r}: {err}") from err
        if head != SQLITE_MAGIC:
            raise BagFormatError(
                f"{str(self.path)!r} is not an sqlite3 file (starts with {head!r})"
            )
        uri = f"file:{urllib.parse.quote(str(self.path.resolve()))}?mode=ro&immutable=1"
        return sqlite3.connect(uri, uri=True)

    def _query(self, fn: Callable[[sqlite3.Connection], Any]) -> Any:
        conn = self._connect()
        try:
            return fn(conn)
        except sqlite3.Error as err:
            raise BagFormatError(f"{str(self.path)!r}: not a rosbag2 sqlite3 file: {err}") from err
        finally:
            conn.close()

    def _topics(self, conn: sqlite3.Connection) -> dict[int, tuple[str, str, str]]:
        rows = conn.execute("SELECT id, name, type, serialization_format FROM topics").fetchall()
        return {int(i): (str(n), str(t), str(f)) for i, n, t, f in rows}

    def scan(self) -> FileScan:
        """Return the topics, counts and time range from the database."""

        def run(conn: sqlite3.Connection) -> FileScan:
            topic_rows = self._topics(conn)
            stats = {
                int(tid): (int(n), int(lo), int(hi))
                for tid, n, lo, hi in conn.execute(
                    "SELECT topic_id, COUNT(*), MIN(timestamp), MAX(timestamp) "
                    "FROM messages GROUP BY topic_id"
                )
            }
            channels = tuple(
                ChannelScan(name, msgtype, fmt, "", "", stats.get(tid, (0, 0, 0))[0])
                for tid, (name, msgtype, fmt) in topic_rows.items()
            )
            starts = [lo for _, lo, _ in stats.values()]
            ends = [hi for _, _, hi in stats.values()]
            return FileScan(
                self.path, "ros2", channels, min(starts, default=None), max(ends, default=None)
            )

        result: FileScan = self._query(run)
        return result

    def messages(self, topics: Collection[str] | None) -> Iterator[RawMessage]:
        """Yield messages ordered by timestamp (ties by row id)."""
        conn = self._connect()
        try:
            topic_rows = self._topics(conn)
            cursor = conn.execute(
                "SELECT topic_id, timestamp, data FROM messages ORDER BY timestamp, id"
            )
            for tid, t_ns, data in cursor:
                name, msgtype, _ = topic_rows.get(int(tid), ("", "", ""))
                if topics is None or name in topics:
                    yield RawMessage(name, int(t_ns), msgtype, bytes(data))
        except sqlite3.Error as err:
            raise BagFormatError(f"{str(self.path)!r}: not a rosbag2 sqlite3 file: {err}") from err
        finally:
            conn.close()


STORAGE_PLUGINS: dict[str, type[McapFile] | type[Sqlite3File]] = {
    "mcap": McapFile,
    "sqlite3": Sqlite3File,
}
"""Storage identifier (as in metadata.yaml) -> backend."""


def storage_for(path: Path) -> McapFile | Sqlite3File:
    """Return the backend for a bare file, by its first bytes.

    Raises:
        BagFormatError: Neither MCAP nor sqlite3.
    """
    try:
        with path.open("rb") as stream:
            head = stream.read(16)
    except OSError as err:
        raise BagFormatError(f"cannot read {str(path)!r}: {err}") from err
    if head.startswith(MCAP_MAGIC):
        return McapFile(path)
    if head.startswith(SQLITE_MAGIC):
        return Sqlite3File(path)
    raise BagFormatError(
        f"{str(path)!r} is neither an MCAP nor an sqlite3 file (starts with {head[:8]!r})"
    )
