"""A recording process killed with SIGKILL leaves a log holding all but its last second."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from rosbags.highlevel import AnyReader

from hil.bag import topics
from hil.bag.reader import BagReader
from hil.bag.recover import recover
from hil.core.samples import PoseSample

# Records pose and IMU at 100 Hz and thruster commands at 20 Hz on a wall-clock
# schedule with the default flush interval (0.5 s) and 1 s splits, printing the
# index of each pose once record() has returned.
CHILD = """
import sys, time
from hil.core.samples import ImuSample, PoseSample, ThrusterCommand
from hil.bag.recorder import Recorder, RecorderConfig
from hil.bag.run_info import RunInfo

recorder = Recorder(sys.argv[1], RunInfo("crash.toml", "h", 1), RecorderConfig(split_s=1.0))
recorder.open()
t0 = time.monotonic()
i = 0
while True:
    t_ns = i * 10_000_000
    recorder.record(PoseSample(t_ns, 0.01 * i, 0.0, 0.0))
    recorder.record(ImuSample(t_ns, 0.0, 0.0, 0.0))
    if i % 5 == 0:
        recorder.record(ThrusterCommand.zero(t_ns))
    print(i, flush=True)
    i += 1
    time.sleep(max(0.0, t0 + 0.01 * i - time.monotonic()))
"""


def test_sigkill_loses_at_most_the_last_second(tmp_path: Path) -> None:
    bag = tmp_path / "run"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    errors = tmp_path / "child.stderr"
    with errors.open("w") as stderr:
        child = subprocess.Popen(
            [sys.executable, "-c", CHILD, str(bag)],
            stdout=subprocess.PIPE,
            stderr=stderr,
            text=True,
            env=env,
        )
    received: list[tuple[float, int]] = []

    def read_stdout() -> None:
        assert child.stdout is not None
        received.extend((time.monotonic(), int(line)) for line in child.stdout)

    reader_thread = threading.Thread(target=read_stdout, daemon=True)
    reader_thread.start()
    try:
        deadline = time.monotonic() + 60.0
        while not received and time.monotonic() < deadline and child.poll() is None:
            time.sleep(0.01)
        assert received, f"recorder never started: {errors.read_text()}"
        time.sleep(2.5)
        killed_at = time.monotonic()
        os.kill(child.pid, signal.SIGKILL)
        child.wait(timeout=10)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait(timeout=10)
    reader_thread.join(timeout=10)
    assert child.stdout is not None
    child.stdout.close()
    assert child.returncode == -signal.SIGKILL
    confirmed = [i for t, i in received if t <= killed_at - 1.0]
    assert confirmed, "the recorder recorded nothing in its first 1.5 s"
    must_have = max(confirmed)

    # Readable as it was left: closed splits plus the unfinished one, up to the last flush.
    with BagReader(bag) as reader:
        assert any("not listed" in p for p in reader.info.problems)
        poses = [r for _, _, r in reader.records([topics.POSE])]
    indices = [round(p.x_m / 0.01) for p in poses if isinstance(p, PoseSample)]
    assert indices[: must_have + 1] == list(range(must_have + 1))
    assert len(indices) <= max(i for _, i in received) + 1

    # One call makes it whole for every other tool.
    recover(bag)
    with AnyReader([bag]) as any_reader:
        pose_connections = [c for c in any_reader.connections if c.topic == topics.POSE]
        assert sum(1 for _ in any_reader.messages(connections=pose_connections)) == len(indices)
        assert any_reader.connections[0].owner is not None
