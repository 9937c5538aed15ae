"""rosbag2 ``metadata.yaml``: write it atomically, read it with clear errors.

The layout is rosbag2's version 9, field for field as rosbags' own writer emits
it, so rosbags' ``Reader``/``AnyReader`` and ``ros2 bag info`` accept it. The same
map goes into each MCAP split as rosbag2's MCAP storage plugin writes it there
(:func:`rosbag2_record`), so that plugin reads a split on its own as rosbag2's.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ruamel.yaml import YAML
from ruamel.yaml.error import YAMLError

from hil.bag.errors import BagFormatError

METADATA_FILE = "metadata.yaml"
VERSION = 9
ROS_DISTRO = "jazzy"
"""The ROS 2 distribution whose message definitions and metadata layout hil writes."""
RECORD_NAME = "rosbag2"
"""Name of rosbag2's MCAP Metadata record."""
UNSET_START_NS = 2**63 - 1
"""rosbag2's starting time of a bag without messages."""


@dataclass(frozen=True, slots=True)
class FileEntry:
    """One closed split.

    Attributes:
        path: File name relative to the bag directory.
        start_ns: Earliest log time in the file (ns).
        end_ns: Latest log time in the file (ns).
        message_count: Messages in the file.
    """

    path: str
    start_ns: int
    end_ns: int
    message_count: int


@dataclass(frozen=True, slots=True)
class TopicEntry:
    """One topic of the bag.

    Attributes:
        name: Topic name.
        msgtype: Full message type, e.g. ``"sensor_msgs/msg/Imu"``.
        message_count: Messages on the topic in the listed files.
        type_hash: RIHS01 type description hash (may be empty).
        offered_qos_profiles: QoS as found in an existing metadata.yaml (a list, or a
            YAML string in versions before 9); empty for hil's own recordings.
    """

    name: str
    msgtype: str
    message_count: int
    type_hash: str = ""
    offered_qos_profiles: list[Any] | str = field(default_factory=list)


def metadata_dict(
    files: Sequence[FileEntry],
    topic_entries: Sequence[TopicEntry],
    custom_data: Mapping[str, str],
) -> dict[str, Any]:
    """Return the ``metadata.yaml`` content for `files` and `topic_entries`."""
    if files:
        start = min(f.start_ns for f in files)
        duration = max(f.end_ns for f in files) - start
    else:
        start, duration = UNSET_START_NS, 0
    return {
        "rosbag2_bagfile_information": {
            "version": VERSION,
            "storage_identifier": "mcap",
            "relative_file_paths": [f.path for f in files],
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": sum(f.message_count for f in files),
            "topics_with_message_count": [
                {
                    "topic_metadata": {
                        "name": t.name,
                        "type": t.msgtype,
                        "serialization_format": "cdr",
                        "offered_qos_profiles": t.offered_qos_profiles,
                        "type_description_hash": t.type_hash,
                    },
                    "message_count": t.message_count,
                }
                for t in topic_entries
            ],
            "compression_format": "",
            "compression_mode": "",
            "files": [
                {
                    "path": f.path,
                    "starting_time": {"nanoseconds_since_epoch": f.start_ns},
                    "duration": {"nanoseconds": f.end_ns - f.start_ns},
                    "message_count": f.message_count,
                }
                for f in files
            ],
            "custom_data": dict(custom_data) or None,
            "ros_distro": ROS_DISTRO,
        }
    }


def rosbag2_record(
    files: Sequence[FileEntry],
    topic_entries: Sequence[TopicEntry],
    custom_data: Mapping[str, str],
) -> dict[str, str]:
    """Return the string map of rosbag2's ``"rosbag2"`` MCAP Metadata record.

    rosbag2_storage_mcap (Jazzy) stores, in each file it closes, ``serialized_metadata``:
    the bag's metadata so far as YAML (the map under ``rosbag2_bagfile_information`` in
    ``metadata.yaml``, version 9, which holds ``ros_distro``); its reader also takes a
    ``ROS_DISTRO`` key, which older distributions wrote. Both are written. The YAML is
    JSON (flow style), as in ``metadata.yaml``.
    """
    info = metadata_dict(files, topic_entries, custom_data)["rosbag2_bagfile_information"]
    return {"serialized_metadata": json.dumps(info, indent=2) + "\n", "ROS_DISTRO": ROS_DISTRO}


def write_metadata(
    bag_dir: Path,
    files: Sequence[FileEntry],
    topic_entries: Sequence[TopicEntry],
    custom_data: Mapping[str, str],
    *,
    fsync: bool = False,
) -> None:
    """Write ``bag_dir/metadata.yaml`` atomically (temporary file, then ``os.replace``).

    Args:
        bag_dir: The bag directory.
        files: Closed splits, in order.
        topic_entries: Topics with their counts over `files`.
        custom_data: String key-value pairs stored as ``custom_data``.
        fsync: Also fsync the file before the rename (survives power loss, slower).
    """
    # JSON is YAML (1.2 flow style, which rosbags, yaml-cpp and PyYAML read), and
    # json.dumps is ~100x faster than ruamel's emitter: this runs at every split.
    text = json.dumps(metadata_dict(files, topic_entries, custom_data), indent=2) + "\n"
    target = bag_dir / METADATA_FILE
    tmp = bag_dir / f".{METADATA_FILE}.tmp"
    with tmp.open("w", encoding="utf-8") as stream:
        stream.write(text)
        if fsync:
            stream.flush()
            os.fsync(stream.fileno())
    os.replace(tmp, target)


def read_metadata(path: Path) -> dict[str, Any]:
    """Read and check the top level of a ``metadata.yaml``; never writes.

    Args:
        path: Path of the ``metadata.yaml`` file.

    Returns:
        The ``rosbag2_bagfile_information`` mapping.

    Raises:
        BagFormatError: Unreadable YAML, or not rosbag2 metadata.
    """
    try:
        text = path.read_text(encoding="utf-8")
        try:
            data = json.loads(text)  # what hil writes; ruamel's parser is ~1000x slower
        except ValueError:
            data = YAML(typ="safe").load(text)
    except (OSError, UnicodeDecodeError, YAMLError) as err:
        raise BagFormatError(f"{str(path)!r}: cannot read rosbag2 metadata: {err}") from err
    info = data.get("rosbag2_bagfile_information") if isinstance(data, dict) else None
    if not isinstance(info, dict):
        raise BagFormatError(f"{str(path)!r}: no 'rosbag2_bagfile_information' mapping")
    version = info.get("version")
    if not isinstance(version, int) or not 1 <= version <= VERSION:
        raise BagFormatError(f"{str(path)!r}: unsupported rosbag2 metadata version {version!r}")
    return info
