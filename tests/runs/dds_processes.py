"""Processes that talk over real DDS on loopback in the end-to-end tests."""

from __future__ import annotations

import os
import signal
import subprocess


def dds_env(domain_id: int) -> dict[str, str]:
    """Return this process's environment on its own ROS domain, discovery on loopback only."""
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    return env


def stop(proc: subprocess.Popen[bytes], timeout_s: float = 15.0) -> int:
    """Stop `proc` as a user would (SIGINT), killing it after `timeout_s`; return its status."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return int(proc.returncode)
