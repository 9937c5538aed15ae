"""A lean MCAP writer: one ``struct.pack`` per message, chunks closed on demand.

The ``mcap`` package's ``Writer`` builds a dataclass and several small writes per
message (about 10 us each), which alone would cost a 3-minute sim run more than
its 5% recording budget. This writer keeps the per-message path to one packed
header appended to a ``bytearray`` plus one index entry (about 1 us), and leaves
every other record to ``mcap``'s own record classes (``mcap.records``), so the
file layout is the one the ``mcap`` package writes: header; chunks, each
holding its schemas, channels and messages (zstd), followed by its message
indexes; data end; a summary with schemas, channels, statistics and chunk
indexes; summary offsets; footer. Tests read it back with ``mcap``'s reader,
rosbags and ``mcap_ros2``.

:meth:`McapChunkWriter.flush` closes the chunk in progress and flushes the
stream: after it, every message so far is in a complete chunk on disk, which is
what a streaming reader recovers when the process is killed.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Callable
from typing import IO, Literal

import lz4.frame  # type: ignore[import-untyped]
import numpy as np
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from numpy.typing import NDArray

MAGIC = b"\x89MCAP0\r\n"
_MESSAGE = struct.Struct("<BQHIQQ")  # opcode, record length, channel, sequence, log, publish
_MESSAGE_FIXED = 2 + 4 + 8 + 8
_INDEX_HEAD = struct.Struct("<BQHI")  # opcode, record length, channel, records length
_MESSAGE_DTYPE = np.dtype(
    {
        "names": ["opcode", "length", "channel", "sequence", "log_time", "publish_time"],
        "formats": ["u1", "<u8", "<u2", "<u4", "<u8", "<u8"],
        "offsets": [0, 1, 9, 11, 15, 23],
        "itemsize": _MESSAGE.size,
    }
)

Compression = Literal["zstd", "lz4", ""]

_COMPRESSORS: dict[str, Callable[[bytes], bytes]] = {
    "zstd": lambda data: zstandard.ZstdCompressor(level=1).compress(data),
    "lz4": lambda data: bytes(lz4.frame.compress(data)),
    "": bytes,
}


def _message_index(channel_id: int, pairs: NDArray[np.uint64]) -> bytes:
    """Serialize a MessageIndex record (as ``mcap.records.MessageIndex`` does) from (k, 2) pairs."""
    size = 16 * len(pairs)
    head = _INDEX_HEAD.pack(Opcode.MESSAGE_INDEX, 2 + 4 + size, channel_id, size)
    return head + np.ascontiguousarray(pairs, dtype="<u8").tobytes()


def _end(builder: RecordBuilder) -> bytes:
    data: bytes = builder.end()  # type: ignore[no-untyped-call]
    return data


class McapChunkWriter:
    """Write an MCAP file to a binary stream, message by message.

    Args:
        stream: Binary stream opened for writing, positioned at 0.
        profile: MCAP profile (``"ros2"``).
        library: Writer identification stored in the header.
        compression: Chunk compression: ``"zstd"``, ``"lz4"`` or ``""``.
        chunk_bytes: Close a chunk when its uncompressed size exceeds this.
    """

    def __init__(
        self,
        stream: IO[bytes],
        *,
        profile: str,
        library: str,
        compression: Compression = "zstd",
        chunk_bytes: int = 1 << 20,
    ) -> None:
        self._stream = stream
        self._compress = _COMPRESSORS[compression]
        self._compression = compression
        self._chunk_bytes = chunk_bytes
        self._schemas: dict[int, Schema] = {}
        self._channels: dict[int, Channel] = {}
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata: list[Metadata] = []
        self._counts: dict[int, int] = {}
        self._message_count = 0
        self._start = 2**64 - 1
        self._end = 0
        self._pos = 0
        # chunk in progress
        self._buf = bytearray()
        self._index: dict[int, list[tuple[int, int]]] = {}
        self._blocks: dict[int, list[NDArray[np.uint64]]] = {}
        self._chunk_start = 2**64 - 1
        self._chunk_end = 0
        self._chunk_messages = 0
        builder = RecordBuilder()
        Header(profile=profile, library=library).write(builder)
        self._write(MAGIC + _end(builder))

    def _write(self, data: bytes) -> None:
        self._stream.write(data)
        self._pos += len(data)

    def _record(self, record: Schema | Channel) -> None:
        builder = RecordBuilder()
        record.write(builder)
        self._buf += _end(builder)

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        """Add a schema; return its id (1, 2, ...)."""
        schema = Schema(id=len(self._schemas) + 1, name=name, encoding=encoding, data=data)
        self._schemas[schema.id] = schema
        self._record(schema)
        return schema.id

    def register_channel(
        self, topic: str, message_encoding: str, schema_id: int, metadata: dict[str, str]
    ) -> int:
        """Add a channel; return its id (0, 1, ...)."""
        channel = Channel(
            id=len(self._channels),
            topic=topic,
            message_encoding=message_encoding,
            schema_id=schema_id,
            metadata=metadata,
        )
        self._channels[channel.id] = channel
        self._counts[channel.id] = 0
        self._record(channel)
        return channel.id

    def add_message(self, channel_id: int, log_time: int, data: bytes, sequence: int) -> None:
        """Append one message (publish time = log time, ns) to the chunk in progress."""
        buf = self._buf
        offset = len(buf)
        buf += _MESSAGE.pack(
            Opcode.MESSAGE, _MESSAGE_FIXED + len(data), channel_id, sequence, log_time, log_time
        )
        buf += data
        index = self._index.get(channel_id)
        if index is None:
            index = self._index[channel_id] = []
        index.append((log_time, offset))
        self._chunk_messages += 1
        if log_time < self._chunk_start:
            self._chunk_start = log_time
        if log_time > self._chunk_end:
            self._chunk_end = log_time
        if offset > self._chunk_bytes:
            self._close_chunk()

    def add_block(
        self, channel_id: int, t_ns: NDArray[np.int64], payloads: NDArray[np.uint8], sequence: int
    ) -> None:
        """Append N messages of one channel at once.

        Args:
            channel_id: Channel of every message.
            t_ns: Log (and publish) times, shape (N,).
            payloads: One payload per row, shape (N, L), uint8.
            sequence: Sequence number of the first message; the rest count up.
        """
        n, size = payloads.shape
        if n == 0:
            return
        header = np.zeros(n, dtype=_MESSAGE_DTYPE)
        header["opcode"] = Opcode.MESSAGE
        header["length"] = _MESSAGE_FIXED + size
        header["channel"] = channel_id
        header["sequence"] = sequence + np.arange(n, dtype=np.uint32)
        header["log_time"] = t_ns
        header["publish_time"] = t_ns
        records = np.empty((n, _MESSAGE.size + size), dtype=np.uint8)
        records[:, : _MESSAGE.size] = header.view(np.uint8).reshape(n, _MESSAGE.size)
        records[:, _MESSAGE.size :] = payloads
        offset = len(self._buf)
        self._buf += records.tobytes()
        index = np.empty((n, 2), dtype="<u8")
        index[:, 0] = t_ns
        index[:, 1] = offset + np.arange(n, dtype=np.uint64) * (_MESSAGE.size + size)
        self._blocks.setdefault(channel_id, []).append(index)
        self._chunk_messages += n
        self._chunk_start = min(self._chunk_start, int(t_ns.min()))
        self._chunk_end = max(self._chunk_end, int(t_ns.max()))
        if offset > self._chunk_bytes:
            self._close_chunk()

    def _indexes(self) -> dict[int, NDArray[np.uint64]]:
        """Return each channel's (log time, offset) pairs of the chunk, sorted by time."""
        out: dict[int, NDArray[np.uint64]] = {}
        for channel_id in {*self._index, *self._blocks}:
            parts = list(self._blocks.get(channel_id, []))
            single = self._index.get(channel_id)
            if single:
                parts.append(np.array(single, dtype="<u8").reshape(-1, 2))
            pairs = np.concatenate(parts) if len(parts) > 1 else parts[0]
            out[channel_id] = pairs[np.argsort(pairs[:, 0], kind="stable")]
        return out

    def _close_chunk(self) -> None:
        if not self._chunk_messages:
            return
        raw = bytes(self._buf)
        chunk = Chunk(
            compression=self._compression,
            data=self._compress(raw),
            message_start_time=self._chunk_start,
            message_end_time=self._chunk_end,
            uncompressed_crc=zlib.crc32(raw),
            uncompressed_size=len(raw),
        )
        builder = RecordBuilder()
        chunk.write(builder)
        chunk_record = _end(builder)
        chunk_offset = self._pos
        self._write(chunk_record)
        index_start = self._pos
        offsets: dict[int, int] = {}
        parts: list[bytes] = []
        size = 0
        for channel_id, pairs in sorted(self._indexes().items()):
            offsets[channel_id] = index_start + size
            part = _message_index(channel_id, pairs)
            parts.append(part)
            size += len(part)
            self._counts[channel_id] += len(pairs)
        indexes = b"".join(parts)
        self._write(indexes)
        self._chunk_indexes.append(
            ChunkIndex(
                message_start_time=self._chunk_start,
                message_end_time=self._chunk_end,
                chunk_start_offset=chunk_offset,
                chunk_length=len(chunk_record),
                message_index_offsets=offsets,
                message_index_length=len(indexes),
                compression=self._compression,
                compressed_size=len(chunk.data),
                uncompressed_size=len(raw),
            )
        )
        self._message_count += self._chunk_messages
        self._start = min(self._start, self._chunk_start)
        self._end = max(self._end, self._chunk_end)
        self._buf = bytearray()
        self._index = {}
        self._blocks = {}
        self._chunk_start, self._chunk_end, self._chunk_messages = 2**64 - 1, 0, 0

    def flush(self) -> None:
        """Close the chunk in progress and flush the stream (not fsync)."""
        self._close_chunk()
        self._stream.flush()

    def add_metadata(self, name: str, metadata: dict[str, str]) -> None:
        """Keep a Metadata record (name, string map) for :meth:`finish`.

        It is written after the last chunk and indexed in the summary, as rosbag2
        writes its ``"rosbag2"`` record.
        """
        self._metadata.append(Metadata(name=name, metadata=dict(metadata)))

    def _write_metadata(self) -> list[MetadataIndex]:
        indexes = []
        for record in self._metadata:
            builder = RecordBuilder()
            record.write(builder)
            data = _end(builder)
            indexes.append(MetadataIndex(offset=self._pos, length=len(data), name=record.name))
            self._write(data)
        return indexes

    def finish(self) -> None:
        """Close the last chunk and write metadata, data end, summary, footer and end magic."""
        self._close_chunk()
        metadata_indexes = self._write_metadata()
        builder = RecordBuilder()
        DataEnd(data_section_crc=0).write(builder)
        self._write(_end(builder))
        summary_start = self._pos
        summary = RecordBuilder()
        offsets: list[SummaryOffset] = []

        def group(
            opcode: int,
            records: list[Schema] | list[Channel] | list[ChunkIndex] | list[MetadataIndex],
        ) -> None:
            start = summary.count
            for record in records:
                record.write(summary)
            offsets.append(SummaryOffset(opcode, summary_start + start, summary.count - start))

        group(Opcode.SCHEMA, list(self._schemas.values()))
        group(Opcode.CHANNEL, list(self._channels.values()))
        start = summary.count
        Statistics(
            attachment_count=0,
            channel_count=len(self._channels),
            channel_message_counts=dict(self._counts),
            chunk_count=len(self._chunk_indexes),
            message_count=self._message_count,
            message_end_time=self._end if self._message_count else 0,
            message_start_time=self._start if self._message_count else 0,
            metadata_count=len(metadata_indexes),
            schema_count=len(self._schemas),
        ).write(summary)
        offsets.append(
            SummaryOffset(Opcode.STATISTICS, summary_start + start, summary.count - start)
        )
        group(Opcode.CHUNK_INDEX, self._chunk_indexes)
        if metadata_indexes:
            group(Opcode.METADATA_INDEX, metadata_indexes)
        offset_start = summary_start + summary.count
        for offset in offsets:
            offset.write(summary)
        data = _end(summary)
        crc = zlib.crc32(data)
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, offset_start), crc)
        self._write(data)
        builder = RecordBuilder()
        Footer(
            summary_start=summary_start, summary_offset_start=offset_start, summary_crc=crc
        ).write(builder)
        self._write(_end(builder) + MAGIC)
        self._stream.flush()
