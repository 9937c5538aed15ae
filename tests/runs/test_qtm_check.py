"""`hil vessel --check` with a ``[qtm]`` table: the QTM feed's rate, latency, drops and lost body.

The pose comes from the test QTM server (loopback TCP); the IMU topic has no publisher
here, so its lines fail: these tests read the QTM lines.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.runs.dds_processes import dds_env, own_domain

pytest.importorskip("qtm_rt")
pytest.importorskip("rclpy")
pytestmark = pytest.mark.ros

from tests.adapters.qtm_server import Faults, QtmTestServer  # noqa: E402

HIL = [sys.executable, "-m", "hil"]


def _still(t_s: float) -> tuple[float, float, float]:
    """At rest inside the coarse arena (lab = arena: the identity transform)."""
    return 0.0, -1.0, 0.0


def _check(tmp_path: Path, offset: int, rate_hz: float, faults: Faults) -> str:
    domain = own_domain(20, 40, offset)
    with QtmTestServer(_still, body="2", rate_hz=rate_hz, faults=faults) as server:
        config = tmp_path / "vessel.toml"
        config.write_text(f'scenario = "coarse"\n[ros]\ndomain_id = {domain}\n'
                          f'[qtm]\nhost = "127.0.0.1"\nport = {server.port}\nbody = "2"\n')
        result = subprocess.run([*HIL, "vessel", "--check", "--config", str(config),
                                 "--seconds", "2"], env=dds_env(domain), capture_output=True,
                                text=True, timeout=180, check=False)
    assert result.returncode == 1, result.stdout + result.stderr  # the IMU has no publisher
    return result.stdout


def test_a_clean_qtm_feed_passes_its_lines(tmp_path: Path) -> None:
    out = _check(tmp_path, 16, 100.0, Faults())
    where = "qtm 127.0.0.1:"
    for what in ("rate", "latency", "drops", "body lost"):
        assert any(line.startswith(f"PASS  {where}") and f"  {what}: " in line
                   for line in out.splitlines()), out
    assert 'PASS  pose feed  premise in force: pose_feed = "qtm-100hz"' in out
    assert "/voyager/measurement/pose" not in out  # the pose topic is not QTM's
    assert "PASS  arena  pose: (+0.00 m, -1.00 m, +0 deg)" in out, out
    latency = next(line for line in out.splitlines() if "  latency: " in line)
    p95_ms = float(latency.split(" ms p95")[0].rsplit(", ", 1)[1])
    assert p95_ms < 500.0, latency  # no pose buffered before the window (1.4 s) counts


@pytest.mark.parametrize(("offset", "rate_hz", "faults", "failing"), [
    (17, 100.0, Faults(drop_frames=frozenset(range(0, 100_000, 10))), "drops: "),
    (18, 10.0, Faults(), "rate: "),
], ids=["every-10th-frame-dropped", "10hz"])
def test_a_faulty_qtm_feed_fails_its_line(tmp_path: Path, offset: int, rate_hz: float,
                                          faults: Faults, failing: str) -> None:
    out = _check(tmp_path, offset, rate_hz, faults)
    line = next(line for line in out.splitlines() if f"  {failing}" in line and "qtm " in line)
    assert line.startswith("FAIL"), out
    if rate_hz == 10.0:
        assert 'set pose_feed = "ros-10hz-receive-stamped"' in line
