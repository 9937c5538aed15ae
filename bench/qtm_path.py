"""Cost of the pose path from a QTM packet to the estimate: `python -m bench qtm_path`.

Per camera frame at 100 Hz of a simulated pass (the vessel at 0.2 m/s turning at 0.1
rad/s), the path the ``qtm`` backend and the runtime run: qtm-rt decodes the data
packet (``QRTPacket``, ``get_6d``), :class:`hil.adapters.qtm_feed.QtmFeed` checks the
frame number, maps QTM's clock onto the run's, turns the 6D body into the lab pose and
the lab pose into the arena, and the EKF fuses it (``Ekf.process_pose``), an IMU
sample fused between frames as on the vessel. Baseline, measured in the same run on the
same frames: the EKF's pose update alone, from ready arena poses. Printed: the median and
99th percentile per frame (us), the ratio to the baseline, and what the path adds to the
EKF's update (target: < 1 ms median). Times are `perf_counter_ns` around each frame.
"""

from __future__ import annotations

import argparse
import math
import struct
import time

import numpy as np
from qtm_rt.packet import QRTPacket

from hil.adapters.frames import ArenaTransform
from hil.adapters.qtm_feed import QtmFeed
from hil.controllers.observer import Ekf
from hil.core.samples import Frame, ImuSample, PoseSample

RATE_HZ = 100.0
NS_PER_FRAME = 10_000_000
TRANSFORM = ArenaTransform(origin_north_m=1.0, origin_east_m=-0.5, yaw_rad=0.3)


def _packet(frame: int, north_m: float, east_m: float, yaw_rad: float) -> bytes:
    """Return a data packet's payload (the 8-byte header off, as qtm-rt hands it over)."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    matrix = (c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0)  # column-major, about down
    body = struct.pack("<12f", 1e3 * north_m, 1e3 * east_m, 0.0, *matrix)
    content = struct.pack("<ihh", 1, 0, 0) + body
    component = struct.pack("<II", 8 + len(content), 5) + content
    return struct.pack("<qII", frame * NS_PER_FRAME // 1000, frame, 1) + component


def _trajectory(n: int) -> list[tuple[float, float, float]]:
    t = np.arange(n) / RATE_HZ
    return [(0.2 * ti * math.cos(0.05 * ti), 0.2 * ti * math.sin(0.05 * ti), 0.1 * ti)
            for ti in t]


def _imu(k: int) -> ImuSample:
    return ImuSample(k * NS_PER_FRAME, 0.0, 0.02, 0.1)


def _path(packets: list[bytes]) -> np.ndarray:
    """Time decode + feed + EKF per frame (ns)."""
    feed = QtmFeed("vessel", TRANSFORM)
    ekf = Ekf()
    out = np.empty(len(packets), dtype=np.int64)
    for k, data in enumerate(packets):
        arrival_ns = k * NS_PER_FRAME + 3_000_000
        ekf.process_imu(_imu(k))
        t0 = time.perf_counter_ns()
        packet = QRTPacket(data)
        info, bodies = packet.get_6d()
        position, rotation = bodies[0]
        pose = feed.frame(arrival_ns, packet.timestamp, packet.framenumber,
                          (position.x, position.y, position.z), rotation.matrix,
                          info.drop_rate)
        assert pose is not None
        ekf.process_pose(pose)
        out[k] = time.perf_counter_ns() - t0
    return out


def _baseline(poses: list[PoseSample]) -> np.ndarray:
    """Time the EKF's pose update alone on the same poses (ns)."""
    ekf = Ekf()
    out = np.empty(len(poses), dtype=np.int64)
    for k, pose in enumerate(poses):
        ekf.process_imu(_imu(k))
        t0 = time.perf_counter_ns()
        ekf.process_pose(pose)
        out[k] = time.perf_counter_ns() - t0
    return out


def main(argv: list[str] | None = None) -> int:
    """Print the pose path's cost per frame against the EKF's update; 0 when < 1 ms added."""
    parser = argparse.ArgumentParser(prog="python -m bench qtm_path", description=__doc__)
    parser.add_argument("--frames", type=int, default=6000, help="camera frames (100 Hz)")
    args = parser.parse_args(argv)
    lab = _trajectory(args.frames)
    packets = [_packet(k, *p) for k, p in enumerate(lab)]
    poses = [TRANSFORM.to_arena(PoseSample(k * NS_PER_FRAME, *p, Frame.LAB_NED))
             for k, p in enumerate(lab)]
    _path(packets[:200])  # compile the EKF's kernels, warm the caches
    _baseline(poses[:200])
    path, base = _path(packets) / 1e3, _baseline(poses) / 1e3
    med_path, med_base = float(np.median(path)), float(np.median(base))
    added = med_path - med_base
    print(f"pose path, QTM packet to estimate: {args.frames} frames at 100 Hz (us per frame)")
    print(f"  {'':<44}{'median':>10}{'p99':>10}{'ratio':>8}")
    print(f"  {'EKF pose update alone (baseline)':<44}{med_base:>10.1f}"
          f"{np.percentile(base, 99):>10.1f}{1.0:>8.2f}")
    print(f"  {'decode + frame + clock + arena + EKF':<44}{med_path:>10.1f}"
          f"{np.percentile(path, 99):>10.1f}{med_path / med_base:>8.2f}")
    print(f"  added by the QTM path: {added:.1f} us median (target < 1000 us: "
          f"{'met' if added < 1000.0 else 'MISSED'})")
    return 0 if added < 1000.0 else 1
