"""The lean MCAP writer's files pass the mcap package's own checks, indexes included."""

from __future__ import annotations

import io
import struct

import pytest
import zstandard
from mcap.reader import SeekingReader
from mcap.records import Chunk, ChunkIndex, MessageIndex
from mcap.stream_reader import StreamReader

from hil.bag.mcap_writer import McapChunkWriter


def _time(i: int) -> int:
    return 1000 + 10 * i - 25 * (i % 3)  # not monotonic across channels, as a recorder sees


def _write(compression: str, chunk_bytes: int, flush_every: int = 0) -> bytes:
    out = io.BytesIO()
    writer = McapChunkWriter(
        out,
        profile="ros2",
        library="test",
        compression=compression,  # type: ignore[arg-type]
        chunk_bytes=chunk_bytes,
    )
    schema = writer.register_schema("std_msgs/msg/Empty", "ros2msg", b"")
    channels = [writer.register_channel(f"/t{i}", "cdr", schema, {"k": "v"}) for i in range(3)]
    for i in range(500):
        writer.add_message(channels[i % 3], _time(i), bytes([i % 256]) * 9, i)
        if flush_every and i % flush_every == flush_every - 1:
            writer.flush()
    writer.finish()
    return out.getvalue()


@pytest.mark.parametrize(
    ("compression", "chunk_bytes", "flush_every"),
    [("zstd", 1 << 20, 0), ("zstd", 1024, 0), ("lz4", 2048, 0), ("", 1 << 20, 37)],
)
def test_file_reads_back_with_valid_crcs_and_indexes(
    compression: str, chunk_bytes: int, flush_every: int
) -> None:
    data = _write(compression, chunk_bytes, flush_every)
    reader = SeekingReader(io.BytesIO(data), validate_crcs=True)
    summary = reader.get_summary()
    assert summary is not None
    assert summary.statistics is not None
    assert summary.statistics.message_count == 500
    assert summary.statistics.message_start_time == min(_time(i) for i in range(500))
    assert summary.statistics.message_end_time == max(_time(i) for i in range(500))
    assert sorted(summary.statistics.channel_message_counts.values()) == [166, 167, 167]
    messages = list(reader.iter_messages(log_time_order=True))
    assert len(messages) == 500
    times = [m.log_time for _, _, m in messages]
    assert times == sorted(times)
    assert {m.sequence for _, _, m in messages} == set(range(500))

    # Every MessageIndex entry points at a message with that time in its chunk.
    chunks: list[Chunk] = []
    checked = 0
    for record in StreamReader(io.BytesIO(data), emit_chunks=True, validate_crcs=True).records:
        if isinstance(record, Chunk):
            chunks.append(record)
        elif isinstance(record, MessageIndex):
            chunk = chunks[-1]
            raw = chunk.data
            if chunk.compression == "zstd":
                raw = zstandard.ZstdDecompressor().decompress(
                    raw, max_output_size=chunk.uncompressed_size
                )
            elif chunk.compression == "lz4":
                import lz4.frame  # type: ignore[import-untyped]

                raw = lz4.frame.decompress(raw)
            for log_time, offset in record.records:
                opcode, _, channel, _, t = struct.unpack_from("<BQHIQ", raw, offset)
                assert (opcode, channel, t) == (0x05, record.channel_id, log_time)
                checked += 1
    assert checked == 500
    assert len(chunks) == len(summary.chunk_indexes) >= 1
    if chunk_bytes == 1024:
        assert len(chunks) > 3
    assert all(isinstance(c, ChunkIndex) for c in summary.chunk_indexes)
    assert data.endswith(b"\x89MCAP0\r\n")


def test_empty_file_is_valid() -> None:
    out = io.BytesIO()
    McapChunkWriter(out, profile="ros2", library="test").finish()
    summary = SeekingReader(io.BytesIO(out.getvalue())).get_summary()
    assert summary is not None
    assert summary.statistics is not None
    assert summary.statistics.message_count == 0
