"""Processes that talk over real DDS on loopback in the end-to-end tests."""

from __future__ import annotations

import os
import signal
import subprocess
import threading
import time
from typing import IO, Any


def dds_env(domain_id: int) -> dict[str, str]:
    """Return this process's environment on its own ROS domain, discovery on loopback only."""
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    return env


def stop(proc: subprocess.Popen[Any], timeout_s: float = 15.0) -> int:
    """Stop `proc` as a user would (SIGINT), killing it after `timeout_s`; return its status."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return int(proc.returncode)


def own_domain(first: int, span: int, offset: int = 0) -> int:
    """Return a ROS domain in [first, first + span) for this test process and `offset`.

    Each module takes its own range (test_ros_e2e 150-229, test_independent_vessel
    60-139, the adapters' tests 100-199, the feed tests 20-59, test_qtm_vessel 1-19,
    test_live_telemetry 140-149), so
    parallel tests stay apart. FastDDS refuses domains above 232.
    """
    return first + (os.getpid() + 7 * offset) % span


class LineTimes:
    """Reads a process's text stream on a thread, noting when each line came (monotonic s)."""

    def __init__(self, stream: IO[str]) -> None:
        self.lines: list[tuple[float, str]] = []
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._thread.start()

    def _read(self, stream: IO[str]) -> None:
        for line in stream:
            with self._lock:
                self.lines.append((time.monotonic(), line.rstrip("\n")))

    def wait_for(self, text: str, timeout_s: float) -> float | None:
        """Return when the first line containing `text` came, waiting up to `timeout_s`."""
        end = time.monotonic() + timeout_s
        while True:
            with self._lock:
                for t, line in self.lines:
                    if text in line:
                        return t
            if time.monotonic() >= end:
                return None
            time.sleep(0.05)

    def text(self) -> str:
        """Return every line read so far."""
        self._thread.join(timeout=0.1)
        with self._lock:
            return "\n".join(line for _, line in self.lines)
