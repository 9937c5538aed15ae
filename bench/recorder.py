"""Cost of recording a 3-minute run, and of reading it back, against plain rosbags.

`python -m bench recorder [--seconds S] [--repeat N]`

Workload: the streams of an S-second run (default 180): pose and IMU at 100 Hz,
estimate, velocity reference, force and thruster commands at 20 Hz (thrusters
fan out to four topics), a decision every 2 s, one obstacle layout. Samples
are built before timing (the runtime builds them anyway).

Writing rows: rosbags (`serialize_cdr` + `rosbags.rosbag2.Writer`, MCAP, the
baseline; message objects prebuilt, so this favours it), the `mcap` package's
Writer fed hil's encoded payloads, hil's per-record encoder alone, and hil's
Recorder: inline (total until `close()` returns) and threaded (the loop thread's
own time in `record()`, and the total until `close()` returns; the writer thread
shares the GIL, so the total is what a CPU-bound sim run pays). Columns: seconds,
us per message, ratio to the baseline, and the share of a 5 s and a 10 s sim run
(the runtime issue's goal and limit).

Reading rows: rosbags `AnyReader` + `deserialize` (baseline), hil's `BagReader`
raw messages, decoded messages, samples/records (fewer items: the lab's
per-thruster topics have no sample) and numpy columns of every fixed-layout
topic. Columns: items per second and the ratio to the baseline.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hil.bag import topics
from hil.bag import typestore as ts
from hil.bag.columns import COLUMN_TYPES, to_columns
from hil.bag.messages import Record, encode
from hil.bag.reader import BagReader
from hil.bag.recorder import Recorder, RecorderConfig
from hil.bag.run_info import RunInfo
from hil.core.records import Decision, ForceCommand, StateEstimate
from hil.core.samples import (
    ImuSample,
    ObstacleLayout,
    PoseSample,
    ThrusterCommand,
    VelocityReference,
)
from hil.core.shapes import Rect


def workload(seconds: float) -> list[Record]:
    """Return the records of a `seconds`-long run in arrival order."""
    out: list[Record] = [
        ObstacleLayout(0, (Rect(0.0, 1.0, 2.0, 3.0), Rect(4.0, 5.0, 0.0, 1.0)))
    ]
    for i in range(int(seconds * 100)):
        t = i * 10_000_000
        s = 0.001 * i
        out.append(PoseSample(t, 1.0 + s, 2.0 - s, math.sin(s)))
        out.append(ImuSample(t, 0.01 * math.cos(s), 0.02, 0.1 * math.sin(s)))
        if i % 5 == 0:
            out.append(StateEstimate(t, 1.0 + s, 2.0 - s, math.sin(s), 0.1, 0.01, 0.02))
            out.append(VelocityReference(t, 0.1, 0.0, 0.02))
            out.append(ForceCommand(t, 1.0, 0.1, 0.05))
            out.append(ThrusterCommand(t, 0.1, 0.3, 0.3, 1.4, -1.4))
        if i % 200 == 0:
            inputs = [[0.1 * k, 0.0, 0.01 * k] for k in range(12)]
            out.append(
                Decision.from_arrays(
                    t, [1.0, 2.0, 0.3], i, 40.0, True, inputs, range(12), 3, 1, "h"
                )
            )
    return out


def _best(fn: Callable[[], float], repeat: int) -> float:
    return min(fn() for _ in range(repeat))


def _write_rosbags(records: list[Record], root: Path) -> Callable[[], float]:
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = ts.typestore()
    prepared: list[tuple[str, int, Any]] = []
    for record in records:
        for topic, payload in encode(record):
            msgtype = topics.TOPIC_TYPES[topic]
            prepared.append((topic, record.t_ns, store.deserialize_cdr(payload, msgtype)))

    def run() -> float:
        path = Path(tempfile.mkdtemp(dir=root)) / "bag"
        start = time.perf_counter()
        with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            connections = {
                topic: writer.add_connection(topic, msgtype, typestore=store)
                for topic, msgtype in topics.TOPIC_TYPES.items()
            }
            for topic, t_ns, msg in prepared:
                msgtype = topics.TOPIC_TYPES[topic]
                writer.write(connections[topic], t_ns, store.serialize_cdr(msg, msgtype))
        return time.perf_counter() - start

    return run


def _write_mcap_package(records: list[Record], root: Path) -> Callable[[], float]:
    from mcap.writer import Writer

    def run() -> float:
        path = Path(tempfile.mkdtemp(dir=root)) / "run.mcap"
        start = time.perf_counter()
        with path.open("wb") as stream:
            writer = Writer(stream)
            writer.start(profile="ros2", library="bench")
            channels: dict[str, int] = {}
            for record in records:
                for topic, payload in encode(record):
                    channel = channels.get(topic)
                    if channel is None:
                        msgtype = topics.TOPIC_TYPES[topic]
                        schema = writer.register_schema(
                            msgtype, "ros2msg", ts.schema_text(msgtype).encode()
                        )
                        channel = channels[topic] = writer.register_channel(topic, "cdr", schema)
                    writer.add_message(channel, record.t_ns, payload, record.t_ns)
            writer.finish()  # type: ignore[no-untyped-call]
        return time.perf_counter() - start

    return run


def _encode_only(records: list[Record]) -> Callable[[], float]:
    def run() -> float:
        start = time.perf_counter()
        for record in records:
            encode(record)
        return time.perf_counter() - start

    return run


def _recorder(
    records: list[Record], root: Path, *, threaded: bool, caller: bool
) -> Callable[[], float]:
    def run() -> float:
        path = Path(tempfile.mkdtemp(dir=root)) / "run"
        recorder = Recorder(path, RunInfo(), RecorderConfig(threaded=threaded))
        recorder.open()
        start = time.perf_counter()
        for record in records:
            recorder.record(record)
        loop = time.perf_counter() - start
        recorder.close()
        total = time.perf_counter() - start
        return loop if caller else total

    return run


def _read_rosbags(path: Path) -> Callable[[], tuple[float, int]]:
    from rosbags.highlevel import AnyReader

    def run() -> tuple[float, int]:
        start = time.perf_counter()
        count = 0
        with AnyReader([path]) as reader:
            for connection, _, raw in reader.messages():
                reader.deserialize(raw, connection.msgtype)
                count += 1
        return time.perf_counter() - start, count

    return run


def _read_hil(path: Path, mode: str) -> Callable[[], tuple[float, int]]:
    def run() -> tuple[float, int]:
        start = time.perf_counter()
        count = 0
        with BagReader(path) as reader:
            if mode == "columns":
                for topic in reader.info.topics:
                    if topic.msgtype in COLUMN_TYPES:
                        raws = list(reader.messages([topic.name]))
                        columns = to_columns(topic.name, topic.msgtype, raws, reader.sample)
                        count += len(columns.t_ns)
            else:
                items = (
                    reader.messages()
                    if mode == "raw"
                    else reader.decoded()
                    if mode == "decoded"
                    else reader.records()
                )
                for _ in items:
                    count += 1
        return time.perf_counter() - start, count

    return run


def main(argv: list[str] | None = None) -> int:
    """Print the writing and reading tables; return 0."""
    parser = argparse.ArgumentParser(prog="python -m bench recorder", description=__doc__)
    parser.add_argument("--seconds", type=float, default=180.0, help="simulated run length (s)")
    parser.add_argument("--repeat", type=int, default=3, help="best of N timings")
    args = parser.parse_args(argv)
    records = workload(args.seconds)
    n_messages = sum(len(encode(r)) for r in records)
    print(f"workload: {args.seconds:.0f} s run, {len(records)} records, {n_messages} messages")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        rows: list[tuple[str, Callable[[], float]]] = [
            ("rosbags Writer + serialize_cdr (baseline)", _write_rosbags(records, root)),
            ("mcap package Writer, hil payloads", _write_mcap_package(records, root)),
            ("hil encode only", _encode_only(records)),
            ("hil Recorder inline", _recorder(records, root, threaded=False, caller=False)),
            (
                "hil Recorder threaded: loop thread",
                _recorder(records, root, threaded=True, caller=True),
            ),
            (
                "hil Recorder threaded: until closed",
                _recorder(records, root, threaded=True, caller=False),
            ),
        ]
        header = f"{'s':>7} {'us/msg':>8} {'ratio':>7} {'% of 5 s':>9} {'% of 10 s':>9}"
        print(f"\n{'writing':<42} {header}")
        baseline = 0.0
        for name, fn in rows:
            seconds = _best(fn, args.repeat)
            baseline = baseline or seconds
            print(
                f"{name:<42} {seconds:7.3f} {seconds / n_messages * 1e6:8.2f} "
                f"{seconds / baseline:7.2f} {seconds / 5 * 100:8.1f}% {seconds / 10 * 100:8.1f}%"
            )

        bag = root / "readback"
        with Recorder(bag, RunInfo()) as recorder:
            for record in records:
                recorder.record(record)
        reads: list[tuple[str, Callable[[], tuple[float, int]]]] = [
            ("rosbags AnyReader + deserialize (baseline)", _read_rosbags(bag)),
            ("hil BagReader raw messages", _read_hil(bag, "raw")),
            ("hil BagReader decoded (rosbags objects)", _read_hil(bag, "decoded")),
            ("hil BagReader samples/records", _read_hil(bag, "records")),
            ("hil BagReader columns (numpy)", _read_hil(bag, "columns")),
        ]
        print(f"\n{'reading (best of N)':<42} {'s':>7} {'items':>7} {'items/s':>10} {'ratio':>7}")
        base_rate = 0.0
        for name, read in reads:
            seconds, count = min(read() for _ in range(args.repeat))
            rate = count / seconds
            base_rate = base_rate or rate
            print(f"{name:<42} {seconds:7.3f} {count:7d} {rate:10.0f} {rate / base_rate:7.2f}")
    return 0
