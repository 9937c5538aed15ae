"""`hil vessel --config` with a ``[qtm]`` table: the pose from QTM, IMU and thrusters on ROS 2.

The same run streams live to Rerun (``--rerun RRD``).

The simulated vessel (`hil sim-vessel`, a process of its own) publishes its true pose on
the lab's ROS topic; this test bridges it into the QTM RT test server (real TCP on
loopback), and `hil vessel` takes its pose from that server through the ``qtm`` backend
while the IMU and the thruster commands stay on DDS. Wall time throughout: QTM's own
timestamps are mapped onto the run's clock.

The camera is in lockstep with the simulated vessel (the server is stepped by each pose the
bridge receives, and each frame carries the pose captured at its time), as QTM stamps a
frame with its capture time: a simulator behind wall time on a loaded machine, or a late
DDS delivery, delays the frames, never mislabels them (a free-running camera that sends the
newest pose it has would stamp an older pose as now, an estimation error of speed x delay
that the filter's consistency watch rightly stops on).
"""

from __future__ import annotations

import contextlib
import math
import os
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest
from rerun.chunk import RrdReader

from hil.bag.reader import BagReader
from hil.bag.run_data import load_run
from hil.core.config import ConfigError
from hil.core.records import Event
from hil.replay.qtm_check import judge_qtm
from hil.replay.regression import Status
from hil.runs.vessel_config import VesselConfig
from tests.adapters.qtm_server import QtmTestServer
from tests.runs.dds_processes import dds_env, own_domain, stop
from tests.views.rrd_store import rows

pytest.importorskip("rclpy")
pytest.importorskip("qtm_rt")

HIL = [sys.executable, "-m", "hil"]


class PoseBridge:
    """The simulated vessel's lab pose, read from its ROS topic, for a stepped QTM server.

    Each pose is kept under its frame number (its stamp since the first pose, at
    `rate_hz`) and moves the server's time to its stamp, so the frame due then carries it.
    """

    def __init__(self, domain_id: int, rate_hz: float = 100.0) -> None:
        import rclpy
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from rclpy.executors import SingleThreadedExecutor

        self.rate_hz = rate_hz
        self._server: QtmTestServer | None = None
        self._context = rclpy.Context()
        rclpy.init(context=self._context, domain_id=domain_id)
        self._node = rclpy.create_node(f"qtm_bridge_{os.getpid()}", context=self._context)
        self._lock = threading.Lock()
        self._first_ns: int | None = None
        self.first_pose = threading.Event()
        """Set once a pose came: the server's time 0, so no frame goes out before it."""
        self._poses: dict[int, tuple[float, float, float]] = {}
        self.count = 0
        self._node.create_subscription(
            PoseWithCovarianceStamped, "/voyager/measurement/pose", self._on_pose, 100
        )
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self._node)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException

        with contextlib.suppress(ExternalShutdownException):
            while self._context.ok():
                self._executor.spin_once(timeout_sec=0.05)

    def _on_pose(self, msg: Any) -> None:
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        with self._lock:
            if self._first_ns is None:
                self._first_ns = stamp_ns
            t_s = (stamp_ns - self._first_ns) / 1e9
            self._poses[round(t_s * self.rate_hz)] = (float(p.x), float(p.y), yaw)
            self.count += 1
            self.first_pose.set()
            if self._server is not None and self._server.now_s() < t_s:
                self._server.advance_to(t_s)

    def attach(self, server: QtmTestServer | None) -> None:
        """Step `server` by the poses from now on (None: stop stepping, before it stops)."""
        with self._lock:
            self._server = server

    def __call__(self, t_s: float) -> tuple[float, float, float]:
        """The pose captured at server time `t_s` (north m, east m, yaw rad); NaN if none."""
        with self._lock:
            return self._poses.get(round(t_s * self.rate_hz), (math.nan, math.nan, math.nan))

    def close(self) -> None:
        """Leave the domain."""
        self._context.try_shutdown()
        self._thread.join(timeout=2.0)


def test_the_vessel_flies_on_poses_from_qtm(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    domain = own_domain(1, 19)  # 1-19: no other test module uses these
    env = dds_env(domain)
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    vessel = subprocess.Popen(
        [*HIL, "sim-vessel", "coarse", "--start=0,-1,180", "--domain-id", str(domain),
         "--duration", "120"],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    bridge = PoseBridge(domain)
    stack = None
    try:
        assert bridge.first_pose.wait(60.0), "the simulated vessel published no pose in 60 s"
        with QtmTestServer(bridge, body="vessel", others=("1",), rate_hz=bridge.rate_hz,
                           stepped=True) as server:
            bridge.attach(server)
            config = tmp_path / "vessel.toml"
            config.write_text(f"""
scenario = "coarse"
[ros]
domain_id = {domain}
[loop]
max_duration_s = 12.0
resynthesis_period_s = 20.0
[qtm]
host = "127.0.0.1"
port = {server.port}
body = "vessel"
""")
            out = tmp_path / "run"
            stack = subprocess.Popen(
                [*HIL, "vessel", "--config", str(config), "--out", str(out),
                 "--rerun", str(tmp_path / "live.rrd")],
                env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            )  # fmt: skip
            try:
                stdout, stderr = stack.communicate(timeout=180)
            finally:
                bridge.attach(None)
    finally:
        if stack is not None and stack.poll() is None:
            stack.kill()
            stack.wait()
        stop(vessel)
        bridge.close()
    # The time limit ends the run (exit 1: not docked in 12 s); it flew on QTM's poses.
    assert stack.returncode == 1, stderr[-3000:] + stdout[-2000:]
    assert f"waiting for pose from QTM at 127.0.0.1:{server.port}, body 'vessel'" in stderr
    assert "not docked after 12 s" in stderr
    with BagReader(out) as reader:
        records = list(reader.records(["/hil/events", "/hil/decision"]))
        counts = {t.name: t.message_count for t in reader.info.topics}
        types = {t.name: t.msgtype for t in reader.info.topics}
    codes = [r.code for _, _, r in records if isinstance(r, Event)]
    assert "qtm_connected" in codes
    assert "pose_lost" not in codes
    assert "estimate_inconsistent" not in codes
    assert counts["/hil/decision"] >= 4  # a decision every 2 s after the filter settled
    assert counts["/voyager/measurement/pose"] > 600  # QTM's 100 Hz, in the lab's frame
    # Every QTM frame as received, and the arena pose is each frame mapped through /tf_static.
    assert counts["/hil/qtm/6d"] >= counts["/hil/pose"] == counts["/voyager/measurement/pose"]
    # The lab's topics in the lab's types (rosbags reads the types from the bag).
    assert types["/voyager/measurement/pose"] == "geometry_msgs/msg/PoseWithCovarianceStamped"
    assert types["/voyager/control/velocity/command"] == "geometry_msgs/msg/Twist"
    assert types["/voyager/control/force/command"] == "geometry_msgs/msg/Wrench"
    assert types["/hil/velocity/command"] == "geometry_msgs/msg/TwistStamped"
    assert types["/tf_static"] == "tf2_msgs/msg/TFMessage"
    run = load_run(out)
    assert run.lab_frame is not None
    assert run.lab_frame.frame_id == "world_ned"
    assert len(run.qtm) == counts["/hil/qtm/6d"]
    assert {(s.body, s.body_index) for s in run.qtm} == {("vessel", 1)}
    judged = judge_qtm(run)
    assert judged.status is Status.PASS, judged.summary
    assert judged.metrics["matched"] == counts["/hil/pose"]
    # Streamed live to Rerun as well (--rerun RRD): every decision and pose.
    store = RrdReader(tmp_path / "live.rrd").store()
    assert rows(store, "/world/controller/safe_inputs") == counts["/hil/decision"]
    assert rows(store, "/world/vessel") == counts["/voyager/measurement/pose"]


def test_a_qtm_table_selects_the_backend_with_the_ros_transform(tmp_path: Path) -> None:
    config = tmp_path / "vessel.toml"
    config.write_text("""
scenario = "coarse"
[ros.transform]
origin_north_m = 1.5
[qtm]
host = "192.168.1.10"
body = "2"
rate_hz = 100
""")
    loaded = VesselConfig.load(config)
    assert loaded.qtm is not None
    assert (loaded.qtm.host, loaded.qtm.body, loaded.qtm.port, loaded.qtm.rate_hz) == (
        "192.168.1.10", "2", 22223, 100
    )
    assert loaded.qtm.transform == loaded.ros.transform
    assert loaded.qtm.transform.origin_north_m == 1.5
    assert VesselConfig.load(_written(tmp_path, 'scenario = "coarse"')).qtm is None


@pytest.mark.parametrize(
    ("table", "needle"),
    [
        ('[qtm]\nhost = "qtm"\n', "body"),
        ('[qtm]\nhost = "qtm"\nbody = "2"\nprot = 22223\n', "prot"),
        ('qtm = "192.168.1.10"\n', "qtm"),
    ],
)
def test_a_bad_qtm_table_is_refused_naming_the_key(
    tmp_path: Path, table: str, needle: str
) -> None:
    with pytest.raises(ConfigError, match=needle):
        VesselConfig.load(_written(tmp_path, f'scenario = "coarse"\n{table}'))


def _written(folder: Path, text: str) -> Path:
    path = folder / "config.toml"
    path.write_text(text)
    return path
