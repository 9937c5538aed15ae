"""Helpers for the bag tests: one record of every stream, the foreign bags, file digests,
a bare MCAP file of given payloads."""

from __future__ import annotations

import hashlib
import math
from pathlib import Path

from mcap.writer import Writer as McapWriter

from hil.bag import topics
from hil.bag import typestore as ts
from hil.bag.messages import Record
from hil.core.records import (
    ControllerReady,
    ControllerSource,
    Decision,
    Event,
    EventLevel,
    ForceCommand,
    StateEstimate,
)
from hil.core.samples import (
    Frame,
    ImuSample,
    ObstacleLayout,
    PoseSample,
    ThrusterCommand,
    VelocityReference,
)
from hil.core.shapes import Rect

REPO_ROOT = Path(__file__).resolve().parents[2]
FOREIGN_BAGS = REPO_ROOT.parent / "shared" / "foreign_bags"


def foreign_bag_paths() -> list[Path]:
    """Every entry of the foreign-bag collection (empty when it is absent)."""
    if not FOREIGN_BAGS.is_dir():
        return []
    return sorted(p for p in FOREIGN_BAGS.iterdir() if p.is_dir() or p.suffix == ".mcap")


def tree_digest(path: Path) -> dict[str, str]:
    """Return sha256 of every file under `path` (or of `path` itself), plus the listing."""
    files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
    return {str(p): hashlib.sha256(p.read_bytes()).hexdigest() for p in files}


def write_raw_mcap(path: Path, messages: list[tuple[str, int, bytes]]) -> Path:
    """Write (topic, log time ns, payload) as given (any order, any payload) to a ROS 2 MCAP."""
    with path.open("wb") as stream:
        writer = McapWriter(stream)
        writer.start(profile="ros2", library="test")
        channels: dict[str, int] = {}
        for topic, t_ns, payload in messages:
            if topic not in channels:
                msgtype = topics.TOPIC_TYPES[topic]
                schema = writer.register_schema(
                    msgtype, "ros2msg", ts.schema_text(msgtype).encode()
                )
                channels[topic] = writer.register_channel(topic, "cdr", schema)
            writer.add_message(channels[topic], t_ns, payload, t_ns)
        writer.finish()  # type: ignore[no-untyped-call]
    return path


def one_of_each(t_ns: int, i: int = 0) -> list[Record]:
    """One record of every stream at `t_ns`, values varying with `i`."""
    s = 0.01 * i
    return [
        PoseSample(t_ns, 1.5 + s, -2.25 - s, 0.3 + s),
        PoseSample(t_ns, 10.0, 20.0, -3.0, Frame.LAB_NED),
        ImuSample(t_ns, 0.125 + s, -0.5, 0.0625),
        StateEstimate(t_ns, 1.5 + s, -2.25, 0.3, 0.1, -0.02, 0.05 + s),
        VelocityReference(t_ns, 0.1 + s, 0.0, -0.05),
        ForceCommand(t_ns, 1.25 + s, -0.5, 0.125),
        ThrusterCommand(t_ns, 0.5, -0.25 + s, 0.75, 1.25, -1.5),
        Decision.from_arrays(
            t_ns,
            [1.5, -2.25, 0.3 + s],
            1234 + i,
            17.0 + i,
            True,
            [[0.1, 0.0, 0.0], [0.2, 0.05, -0.1]],
            [3, 7],
            7,
            2,
            "sha256:abc",
        ),
        Decision.from_arrays(t_ns, [0, 0, 0], -1, math.inf, False, [], [], -1, 2, "sha256:abc"),
        ObstacleLayout(t_ns, (Rect(0.0, 1.0, 2.0, 3.5 + s), Rect(-1.0, 0.5, 0.0, 0.25))),
        Event(t_ns, EventLevel.WARN, "pose_stale", f"no pose for 0.{i} s"),
        ControllerReady(t_ns, 3 + i, 0.25 + s, ControllerSource.MEMORY, i % 2 == 0, 1.5, -1),
    ]
