"""End to end over real DDS: the simulated vessel and the stack in two processes.

`hil sim-vessel` publishes pose, IMU and /clock on the lab's topics; `hil vessel`
runs the stack on the ROS backend with ROS sim time, docks in the coarse
scenario and records the run. Each test run gets its own ROS_DOMAIN_ID and
stays on loopback; both processes are killed whatever happens.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hil.bag.reader import BagReader
from hil.core.records import Event
from hil.core.samples import ThrusterCommand
from tests.runs.dds_processes import dds_env, stop

NS_PER_S = 1_000_000_000

pytest.importorskip("rclpy")
pytestmark = pytest.mark.ros

HIL = [sys.executable, "-m", "hil"]


def test_stack_docks_the_simulated_vessel_over_dds(tmp_path: Path) -> None:
    domain = 150 + os.getpid() % 80
    config = tmp_path / "vessel.toml"
    config.write_text(f"""
scenario = "coarse"
runs_dir = "{tmp_path / "runs"}"
[ros]
use_sim_time = true
domain_id = {domain}
[loop]
max_duration_s = 120.0
resynthesis_period_s = 20.0
""")
    out = tmp_path / "run"
    # Start below O2, heading west (a winning start): along the bottom into the target.
    vessel = subprocess.Popen(
        [
            *HIL,
            "sim-vessel",
            "coarse",
            "--clock",
            "--speed",
            "2",
            "--start=0,-1,180",
            "--domain-id",
            str(domain),
            "--duration",
            "400",
        ],
        env=dds_env(domain),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    stack = None
    try:
        stack = subprocess.Popen(
            [*HIL, "vessel", "--config", str(config), "--out", str(out), "--json"],
            env=dds_env(domain),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        stdout, stderr = stack.communicate(timeout=240)
    finally:
        if stack is not None and stack.poll() is None:
            stack.kill()
            stack.wait()
        stop(vessel)
    assert stack.returncode == 0, stderr[-3000:] + stdout[-3000:]
    summary = json.loads(stdout.strip().splitlines()[-1])
    assert summary["docked"] is True
    assert summary["backend"] == "ros"
    assert summary["hull_contacts"] == 0
    with BagReader(out) as reader:
        info = reader.info
        counts = {t.name: t.message_count for t in info.topics}
    assert counts["/hil/decision"] == summary["decisions"]
    # One clock: the bag spans the run and the poses recorded while the stack set up
    # (synthesis, 5-40 s of /clock at speed 2 on a loaded CI machine), not the /clock
    # time before the stack joined (that bug made a 42-s run span 151 s): at most the
    # stack's own wall time at speed 2.
    assert summary["duration_s"] < info.duration_ns / 1e9 < 2.0 * summary["wall_s"] + 5.0
    assert "waiting for pose on /voyager/measurement/pose" in stderr
    assert counts["/voyager/measurement/pose"] > 1000
    assert info.run is not None
    assert info.run.backend == "ros"


def _coarse_vessel(tmp_path: Path, domain: int) -> tuple[Path, subprocess.Popen[bytes]]:
    """Write a vessel config of the coarse scenario on `domain`; start `hil sim-vessel` there.

    Returns the config's path and the simulated vessel's process (stop it with `stop`).
    """
    config = tmp_path / "vessel.toml"
    config.write_text(f"""
scenario = "coarse"
[ros]
domain_id = {domain}
""")
    vessel = subprocess.Popen(
        [*HIL, "sim-vessel", "coarse", "--domain-id", str(domain)],
        env=dds_env(domain), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    return config, vessel


def test_sigterm_zeroes_thrust_and_closes_the_log(tmp_path: Path) -> None:
    domain = 150 + (os.getpid() + 40) % 80
    config, vessel = _coarse_vessel(tmp_path, domain)
    out = tmp_path / "run"
    stack = subprocess.Popen(
        [*HIL, "vessel", "--config", str(config), "--out", str(out)],
        env=dds_env(domain),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        # Wait until the stack is recording the vessel's poses, then ask it to stop.
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not (out / "metadata.yaml").exists():
            time.sleep(0.2)
        time.sleep(4.0)
        stack.send_signal(signal.SIGTERM)
        _, stderr = stack.communicate(timeout=30)
    finally:
        if stack.poll() is None:
            stack.kill()
            stack.wait()
        stop(vessel)
    assert stack.returncode in (0, 1), stderr[-3000:]
    assert "stopped: stopped by SIGTERM" in stderr
    with BagReader(out) as reader:
        records = list(reader.records(["/hil/events", "/hil/thrusters"]))
        info = reader.info
    # Wall time: every topic on the epoch clock, the span seconds, not decades.
    assert info.start_ns is not None
    assert info.start_ns > 1_000_000_000 * NS_PER_S
    assert info.duration_ns < 120 * NS_PER_S
    codes = [r.code for _, _, r in records if isinstance(r, Event)]
    # Stopped, then braked to rest (or cut where there was nothing to brake).
    assert "stopped" in codes
    assert codes[-1] in ("stopped", "at_rest")
    commands = [r for _, _, r in records if isinstance(r, ThrusterCommand)]
    last = commands[-1]
    assert (last.tunnel, last.port, last.starboard) == (0.0, 0.0, 0.0)


# `hil vessel` with a SIGTERM sent to itself as the pose feed's rate window opens (after
# the first pose, before the loop's first tick): the moment no handler covered before.
_SIGTERM_IN_THE_RATE_WINDOW = """
import os, signal, sys
import hil.runs.vessel_run as vessel_run
from hil.cli import main

measure = vessel_run.measure_rate

def measure_after_a_sigterm(*args, **kwargs):
    os.kill(os.getpid(), signal.SIGTERM)
    return measure(*args, **kwargs)

vessel_run.measure_rate = measure_after_a_sigterm
raise SystemExit(main(sys.argv[1:]))
"""


def test_a_sigterm_before_the_first_tick_closes_the_log(tmp_path: Path) -> None:
    domain = 150 + (os.getpid() + 20) % 80
    config, vessel = _coarse_vessel(tmp_path, domain)
    out = tmp_path / "run"
    try:
        stack = subprocess.run(
            [sys.executable, "-c", _SIGTERM_IN_THE_RATE_WINDOW, "vessel", "--config",
             str(config), "--out", str(out)],
            env=dds_env(domain), capture_output=True, text=True, timeout=120, check=False,
        )  # fmt: skip
    finally:
        stop(vessel)
    assert stack.returncode in (0, 1), stack.stderr[-3000:]
    assert "stopped: stopped by SIGTERM while waiting for pose" in stack.stderr
    assert "running: recording" not in stack.stderr
    with BagReader(out) as reader:
        records = list(reader.records(["/hil/events", "/hil/thrusters"]))
    events = [r for _, _, r in records if isinstance(r, Event)]
    assert [e.text for e in events if e.code == "stopped"] == [
        "stopped by SIGTERM while waiting for pose"
    ]
    # Braked to rest from where it lay (or cut where there was nothing to brake), thrust off.
    assert events[-1].code in ("stopped", "at_rest")
    last = [r for _, _, r in records if isinstance(r, ThrusterCommand)][-1]
    assert (last.tunnel, last.port, last.starboard) == (0.0, 0.0, 0.0)
