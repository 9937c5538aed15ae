"""The simulated C/S Voyager as a ROS 2 node (`hil sim-vessel`).

It publishes the motion-capture pose (in the lab's NED frame, through the
configured arena transform) and the IMU on the lab's topics, applies the
thruster commands it receives, and can publish `/clock` so that both sides run
on simulated time faster than real time. The stack on the other side talks to
it exactly as it will talk to the vessel.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

from hil.adapters.ros import (
    RosBackendError,
    RosConfig,
    fill_imu_msg,
    fill_pose_msg,
    init_context,
    thruster_command_from_components,
)
from hil.adapters.sim import SimWorld
from hil.core.clock import NS_PER_S, WallAnchor, fill_stamp
from hil.core.samples import ThrusterCommand

# Simulated time advanced per publication cycle (s).
_CYCLE_S = 0.01
# Wall seconds between status lines.
STATUS_PERIOD_S = 5.0


def _quiet(_line: str) -> None:
    pass


class SimVesselNode:
    """A :class:`SimWorld` behind the lab's ROS 2 topics.

    Args:
        world: The simulated world (its sensors, plant and obstacles).
        config: Topics, frames and domain; `use_sim_time` makes it publish `/clock`.
        speed: Simulated seconds per wall second (1 = real time).
    """

    def __init__(self, world: SimWorld, config: RosConfig, speed: float = 1.0) -> None:
        if not speed > 0:
            raise ValueError(f"speed must be positive, got {speed!r}")
        self.world = world
        self.config = config
        self.speed = speed
        self._stop = threading.Event()
        self._wrench: dict[str, tuple[float, float]] = {
            "tunnel": (0.0, 0.0),
            "port": (0.0, 0.0),
            "starboard": (0.0, 0.0),
        }
        self._command: ThrusterCommand | None = None
        self._lock = threading.Lock()
        self.commands_received = 0
        self._progress: Callable[[str], None] = _quiet
        self.stopped_by: str | None = None
        """What stopped the node (a signal's name), set by whoever calls :meth:`stop`."""
        self._wall: WallAnchor | None = None

    def stop(self) -> None:
        """Ask :meth:`run` to return (safe from a signal handler)."""
        self._stop.set()

    def status_line(self, t_ns: int) -> str:
        """Return one line: simulated time, the true pose, thruster messages received.

        Where simulated time fell too far behind the wall to catch up (a paused process),
        the line says how often.
        """
        x, y, psi = (float(v) for v in self.world.eta)
        wall = self._wall
        slips = ("" if wall is None or wall.slips == 0 else
                 f", fell behind the wall clock {wall.slips} times "
                 f"({wall.slipped_ns / 1e6:.0f} ms skipped)")
        return (f"t={t_ns / NS_PER_S:6.1f} s  at ({x:+.2f} m, {y:+.2f} m, "
                f"{math.degrees(psi):+.0f} deg)  thruster messages {self.commands_received}"
                f"{slips}")

    def _on_wrench(self, name: str, msg: Any) -> None:
        with self._lock:
            self._wrench[name] = (float(msg.force.x), float(msg.force.y))
            self.commands_received += 1

    def run(self, duration_s: float | None = None,
            progress: Callable[[str], None] = _quiet) -> None:
        """Publish and simulate until stopped or `duration_s` of simulated time has passed.

        Args:
            duration_s: Simulated seconds to run; None until :meth:`stop`.
            progress: Receives a line on start, a status line every
                :data:`STATUS_PERIOD_S` of wall time, and why it stopped.

        Raises:
            RosBackendError: rclpy or the message packages are missing, or ROS 2
                cannot start on the domain.
        """
        self._progress = progress
        try:
            import rclpy
            from geometry_msgs.msg import PoseWithCovarianceStamped, Wrench
            from rclpy.executors import SingleThreadedExecutor
            from rosgraph_msgs.msg import Clock
            from sensor_msgs.msg import Imu
        except ImportError as err:
            raise RosBackendError(f"sim-vessel needs rclpy and the ROS message packages ({err})"
                                  ) from err
        cfg = self.config
        context = rclpy.Context()
        domain = init_context(rclpy, context, cfg.domain_id, cfg.ros_args)
        node = rclpy.create_node("hil_sim_vessel", context=context)
        try:
            pose_pub = node.create_publisher(PoseWithCovarianceStamped, cfg.topics.pose,
                                             cfg.qos_depth)
            imu_pub = node.create_publisher(Imu, cfg.topics.imu, cfg.qos_depth)
            clock_pub = node.create_publisher(Clock, "/clock", 10) if cfg.use_sim_time else None
            for name in ("tunnel", "port", "starboard"):
                node.create_subscription(
                    Wrench, getattr(cfg.topics, name),
                    lambda msg, n=name: self._on_wrench(n, msg), cfg.qos_depth)
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(node)
            clock = (f"/clock at {self.speed:g}x real time" if clock_pub is not None
                     else "wall time")
            progress(f"publishing pose on {cfg.topics.pose} and IMU on {cfg.topics.imu}, "
                     f"thrust from {cfg.topics.tunnel}, {cfg.topics.port}, {cfg.topics.starboard} "
                     f"(ROS domain {domain}, {clock})")
            self._loop(executor, pose_pub, imu_pub, clock_pub, PoseWithCovarianceStamped, Imu,
                       Clock, duration_s)
            executor.shutdown()
        finally:
            node.destroy_node()
            context.try_shutdown()

    def _loop(self, executor: Any, pose_pub: Any, imu_pub: Any, clock_pub: Any,
              pose_type: Any, imu_type: Any, clock_type: Any, duration_s: float | None) -> None:
        world = self.world
        next_status = time.monotonic() + STATUS_PERIOD_S
        cycle_ns = round(_CYCLE_S * NS_PER_S)
        t_ns = world.clock.now_ns()
        # On /clock, stamps are simulated time and the wall only paces it. In wall time,
        # samples carry the system clock (the ROS clock) at their capture, as the real
        # sensors do, however the clock is set meanwhile.
        wall = WallAnchor(t_ns, self.speed)
        self._wall = wall

        def stamp(t_capture_ns: int) -> int:
            return t_capture_ns if clock_pub is not None else wall.system_of(t_capture_ns)

        while not self._stop.is_set():
            if duration_s is not None and t_ns >= duration_s * NS_PER_S:
                self._progress(f"stopped: {duration_s:g} s simulated (--duration)")
                return
            if time.monotonic() >= next_status:
                next_status += STATUS_PERIOD_S
                self._progress(self.status_line(t_ns))
            executor.spin_once(timeout_sec=0.0)
            with self._lock:
                port, stbd, tunnel = self._wrench["port"], self._wrench["starboard"], \
                    self._wrench["tunnel"]
            self._command = thruster_command_from_components(t_ns, tunnel[0], port, stbd,
                                                             self._command)
            world.thrusters.send(self._command)
            t_ns += cycle_ns
            world.clock.sleep_until(t_ns)
            if clock_pub is not None:
                msg = clock_type()
                fill_stamp(msg.clock, t_ns)
                clock_pub.publish(msg)
            for pose in world.pose.poll():
                out = pose_type()
                fill_pose_msg(out, replace(pose, t_ns=stamp(pose.t_ns)),
                              self.config.transform, self.config.pose_frame_id)
                pose_pub.publish(out)
            for imu in world.imu.poll():
                out = imu_type()
                fill_imu_msg(out, replace(imu, t_ns=stamp(imu.t_ns)))
                imu_pub.publish(out)
            # The step emitted what its sensors captured up to its start: published now, at
            # most a period early; then wait for the step's end to be due.
            wall.wait_for(t_ns)
