"""Recover a bag whose recorder was killed: rewrite truncated splits, list them in metadata.

A killed recorder leaves its current split without summary and footer, and not
yet listed in ``metadata.yaml``. :class:`hil.bag.reader.BagReader` reads such a
bag as it is; :func:`recover` makes it whole for every other tool (rosbags,
``ros2 bag``, Foxglove): each truncated split is stream-read (every complete
chunk is kept), written again as a finished MCAP file next to it and renamed
over it, and ``metadata.yaml`` is rewritten atomically to list every split.

:func:`inspect_recovery` only reads and says what :func:`recover` would do.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import Any

from mcap.records import Channel, Schema
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from hil import __version__
from hil.bag import topics
from hil.bag.errors import BagError, BagNotFoundError, RecoveryError
from hil.bag.metadata import METADATA_FILE, FileEntry, TopicEntry, read_metadata, write_metadata
from hil.bag.storage import FileScan, McapFile, storage_for
from hil.bag.typestore import typestore


@dataclass(frozen=True, slots=True)
class RecoveryReport:
    """What recovery did (or would do).

    Attributes:
        path: The bag directory or file.
        rewritten: Files rewritten from their complete records.
        removed: Truncated files without a single complete message, removed.
        messages: Messages in the bag after recovery.
        problems: What each rewritten file lost, one line each.
    """

    path: Path
    rewritten: tuple[str, ...]
    removed: tuple[str, ...]
    messages: int
    problems: tuple[str, ...]

    @property
    def changed(self) -> bool:
        """Whether recovery changes (or changed) anything."""
        return bool(self.rewritten or self.removed)


def _old_topics(bag_dir: Path) -> dict[str, dict[str, Any]]:
    """Return the topic_metadata of the existing metadata.yaml, by topic name."""
    meta = read_metadata(bag_dir / METADATA_FILE)
    out: dict[str, dict[str, Any]] = {}
    for entry in meta.get("topics_with_message_count") or []:
        topic = entry.get("topic_metadata") if isinstance(entry, dict) else None
        if isinstance(topic, dict) and "name" in topic:
            out[str(topic["name"])] = topic
    return out


def _bag_files(bag_dir: Path) -> tuple[list[Path], dict[str, str]]:
    meta_path = bag_dir / METADATA_FILE
    if not meta_path.is_file():
        raise RecoveryError(f"{str(bag_dir)!r} has no {METADATA_FILE}; it is not a rosbag2 bag")
    meta = read_metadata(meta_path)
    if meta.get("storage_identifier") != "mcap":
        raise RecoveryError(
            f"{str(bag_dir)!r}: only MCAP bags can be recovered, "
            f"not {meta.get('storage_identifier')!r}"
        )
    listed = [bag_dir / PurePath(str(n)).name for n in meta.get("relative_file_paths") or []]
    extra = sorted(p for p in bag_dir.glob("*.mcap") if p not in listed)
    custom = meta.get("custom_data") or {}
    return [p for p in listed if p.exists()] + extra, {str(k): str(v) for k, v in custom.items()}


def _plan(path: Path) -> tuple[list[McapFile], list[FileScan], dict[str, str]]:
    if not path.exists():
        raise BagNotFoundError(f"{str(path)!r} does not exist")
    if path.is_dir():
        paths, custom = _bag_files(path)
    else:
        paths, custom = [path], {}
    files = []
    for file_path in paths:
        backend = storage_for(file_path)
        if not isinstance(backend, McapFile):
            raise RecoveryError(f"{str(file_path)!r} is not an MCAP file")
        files.append(backend)
    return files, [f.scan() for f in files], custom


def inspect_recovery(path: str | Path) -> RecoveryReport:
    """Say what :func:`recover` would do, without writing anything.

    Raises:
        BagNotFoundError: `path` does not exist.
        RecoveryError: Not an MCAP bag or file.
    """
    path = Path(path)
    _, scans, _ = _plan(path)
    damaged = [s for s in scans if s.problem]
    return RecoveryReport(
        path,
        tuple(s.path.name for s in damaged if s.message_count),
        tuple(s.path.name for s in damaged if not s.message_count),
        sum(s.message_count for s in scans),
        tuple(f"{s.path.name}: {s.problem}" for s in damaged),
    )


def _rewrite(source: McapFile) -> None:
    """Write the complete records of `source` to a new MCAP file and rename it over."""
    tmp = source.path.with_name(f".{source.path.name}.recover.tmp")
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    pending: dict[int, Channel] = {}
    with tmp.open("wb") as stream:
        writer = McapWriter(stream, compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library=f"hil {__version__} (recovered)")
        for kind, record in source.records():
            if kind == "schema" and isinstance(record, Schema):
                schema_ids[record.id] = writer.register_schema(
                    record.name, record.encoding, record.data
                )
            elif kind == "channel" and isinstance(record, Channel):
                pending[record.id] = record
            elif kind == "message":
                cid = channel_ids.get(record.channel_id)
                if cid is None:
                    channel = pending.get(record.channel_id)
                    if channel is None:
                        continue  # a message whose channel was lost cannot be decoded
                    cid = writer.register_channel(
                        channel.topic,
                        channel.message_encoding,
                        schema_ids.get(channel.schema_id, 0),
                        dict(channel.metadata),
                    )
                    channel_ids[record.channel_id] = cid
                writer.add_message(
                    cid, record.log_time, record.data, record.publish_time, record.sequence
                )
        writer.finish()  # type: ignore[no-untyped-call]
        stream.flush()
        os.fsync(stream.fileno())
    os.replace(tmp, source.path)


def recover(path: str | Path) -> RecoveryReport:
    """Recover a bag directory (or a bare MCAP file) in place.

    Truncated splits are rewritten from their complete records; a truncated split
    without a complete message is removed; a bag directory gets a new
    ``metadata.yaml`` listing every split, its ``custom_data`` kept. A bag that
    needs nothing is left byte-for-byte as it was.

    Args:
        path: Bag directory or ``.mcap`` file.

    Returns:
        What was done.

    Raises:
        BagNotFoundError: `path` does not exist.
        RecoveryError: Not an MCAP bag, or a file cannot be written.
    """
    path = Path(path)
    report = inspect_recovery(path)
    files, scans, custom = _plan(path)
    unlisted = False
    if path.is_dir():
        listed = read_metadata(path / METADATA_FILE).get("relative_file_paths") or []
        unlisted = any(f.path.name not in listed for f in files)
    if not report.changed and not unlisted:
        return report
    kept: list[FileScan] = []
    try:
        for backend, scan in zip(files, scans, strict=True):
            if not scan.problem:
                kept.append(scan)
            elif scan.message_count:
                _rewrite(backend)
                kept.append(McapFile(backend.path).scan())
            else:
                backend.path.unlink()
        if path.is_dir():
            _write_metadata(path, kept, custom)
    except (OSError, BagError) as err:
        raise RecoveryError(f"cannot recover {str(path)!r}: {err}") from err
    return report


def _write_metadata(bag_dir: Path, scans: list[FileScan], custom: dict[str, str]) -> None:
    entries = [
        FileEntry(s.path.name, s.start_ns or 0, s.end_ns or 0, s.message_count)
        for s in scans
        if s.message_count
    ]
    counts: dict[str, int] = {}
    types: dict[str, str] = {}
    qos: dict[str, str] = {}
    for scan in scans:
        for ch in scan.channels:
            counts[ch.topic] = counts.get(ch.topic, 0) + ch.message_count
            types.setdefault(ch.topic, ch.msgtype)
            qos.setdefault(ch.topic, ch.qos)
    # QoS comes from the MCAP channels (rosbags matches them against metadata.yaml and
    # yields nothing on a mismatch); the rest of what the old metadata said is kept.
    old = _old_topics(bag_dir)
    topic_entries = []
    for name in sorted(counts):
        digest = str(old.get(name, {}).get("type_description_hash", ""))
        if not digest and name in topics.TOPIC_TYPES:
            with contextlib.suppress(Exception):
                digest = str(typestore().hash_rihs01(types[name]))
        profiles = qos[name] or old.get(name, {}).get("offered_qos_profiles", [])
        topic_entries.append(TopicEntry(name, types[name], counts[name], digest, profiles))
    write_metadata(bag_dir, entries, topic_entries, custom, fsync=True)
