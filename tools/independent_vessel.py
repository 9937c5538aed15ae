#!/usr/bin/env python3
"""An independent C/S Voyager simulator on the lab's ROS 2 topics (issue 11's outside check).

Written from ``../shared/VESSEL.md`` and ``../shared/PAPER.md`` only: it imports nothing
of ``hil`` and speaks only the lab's interface, so ``hil vessel`` drives it exactly as
it drives the vessel in the tank:

* publishes ``/voyager/measurement/pose`` (geometry_msgs/PoseWithCovarianceStamped,
  frame ``world_ned``: the mocap rigid body's position north/east and its heading
  about down) and ``/voyager/measurement/imu`` (sensor_msgs/Imu, frame
  ``voyager/imu_link``, body FRD like the vessel: specific force x/y, yaw rate z, no
  orientation), each at its own rate;
* subscribes ``/voyager/thruster/{tunnel,port,starboard}/command``
  (geometry_msgs/Wrench, normalized: the tunnel's force.x, each azimuth's thrust
  vector (force.x, force.y) in the body frame);
* with ``--clock``, publishes ``/clock`` (ROS sim time from 0) and runs ``--speed``
  times faster than real time (``--lockstep-s LEAD``: never more than LEAD simulated
  seconds past the latest thruster command, so that a stack starved of CPU sees a
  slower clock instead of late ticks); without it, stamps are the wall clock.

It records its own true state, one row per physics cycle, to a CSV file in the lab
frame: ``t_ns`` (the clock of the message stamps), ``north_m``, ``east_m``,
``yaw_rad`` (world_ned), ``u_mps``, ``v_mps``, ``r_radps`` (body FRD). ``hil judge``
(or :func:`hil.replay.truth.judge_log_on_truth`) holds a ``hil vessel`` run to the
guarantee on this state.

With ``--hold-until-commanded`` (the default) the hull is held at the start pose, the
clock at its start, until the first thruster command arrives (the stack is up and
ticking), then released with the start velocity: a moving start then begins when the
controller takes over, as in ``hil campaign``.

Model (VESSEL.md, C/S Enterprise I coefficients; Fossen's body frame x forward, y
starboard, z down)::

    eta_dot = R(psi) nu,   M nu_dot + C(nu) nu + D(nu) nu = tau

integrated by scipy's adaptive RK45 over each 10-ms cycle (not the paper's forward
Euler), the thrust ramping linearly inside the cycle as the rate limit moves it.

Thrusters (VESSEL.md): tau = sum of each thruster's force (Fx, Fy) at (lx, ly) with
moment lx Fy - ly Fx; tunnel at (0.3875, 0) pushing along y with 2.629 N per unit
command, saturated at 0.7; azimuths at (-0.4574, -/+0.055) with 1.03 N per unit of the
commanded vector, its length saturated at 1. Each normalized wire value moves at most
0.1 per 20-Hz step (2 per second). Pods point where the commanded vector points at
once, unless ``--azimuth-rate-deg-s`` gives them a slew rate: then a pod turns the
short way (reversing its propeller rather than turning past 90 degrees) and delivers
the commanded vector's component along its axis.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import math
import signal
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

FloatArray = NDArray[np.float64]
NS_PER_S = 1_000_000_000
CYCLE_NS = 10_000_000  # physics and publication cycle (10 ms)

# -- the hull (VESSEL.md, C/S Enterprise I) --------------------------------------------

MASS_KG = 14.11
IZ_KGM2 = 1.76
XG_M = 0.0375
X_UDOT, Y_VDOT, Y_RDOT, N_VDOT, N_RDOT = -2.0, -10.0, 0.0, 0.0, -1.0
XU, XUU, XUUU = -0.6555, 0.3545, -3.787
YV, YVV, YVVV, YR, YRR, YRRR, YRV, YVR = -1.3443, -2.776, -65.91, -7.25, -3.45, 0.0, -0.805, -0.845
NV, NVV, NVVV, NR, NRR, NRRR, NRV, NVR = 0.0, -0.2088, 0.0, -1.9, -0.75, 0.0, 0.130, 0.080

# M = M_RB + M_A (VESSEL.md gives it as [[16.11, 0, 0], [0, 24.11, 0.5291], [0, 0.5291, 2.76]]).
M = np.array([
    [MASS_KG - X_UDOT, 0.0, 0.0],
    [0.0, MASS_KG - Y_VDOT, MASS_KG * XG_M - Y_RDOT],
    [0.0, MASS_KG * XG_M - N_VDOT, IZ_KGM2 - N_RDOT],
])
M_INV = np.linalg.inv(M)

# -- the thrusters (VESSEL.md, C/S Voyager) --------------------------------------------

TUNNEL_X_M = 0.3875
AZIMUTH_X_M = -0.4574
PORT_Y_M, STARBOARD_Y_M = -0.055, 0.055
TUNNEL_GAIN_N = 2.629
AZIMUTH_GAIN_N = 1.03
TUNNEL_LIMIT = 0.7
COMMAND_RATE_PER_S = 0.1 * 20.0  # 0.1 per step of the lab's 20-Hz allocator
PORT_REFERENCE_RAD, STARBOARD_REFERENCE_RAD = math.pi / 2, -math.pi / 2

# -- sensors (orders of magnitude: Qualisys ~1 mm and 0.1 deg; BNO055) ------------------

GRAVITY_MPS2 = 9.80665


def wrap(angle_rad: float) -> float:
    """Return the angle wrapped to [-pi, pi)."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi


def coriolis(nu: FloatArray) -> FloatArray:
    """Return C(nu), shape (3, 3) (VESSEL.md: c13, c23, skew-symmetric)."""
    u, v, r = nu
    c13 = (-MASS_KG * XG_M + Y_RDOT) * r + (-MASS_KG + Y_VDOT) * v
    c23 = (MASS_KG - X_UDOT) * u
    return np.array([[0.0, 0.0, c13], [0.0, 0.0, c23], [-c13, -c23, 0.0]])


def damping(nu: FloatArray) -> FloatArray:
    """Return D(nu), shape (3, 3), in the usual form for this parameter set.

    Notes:
        Skåtun 2011, as VESSEL.md states it: d11 = -Xu - Xuu|u| - Xuuu u^2,
        d22 = -Yv - Yvv|v| - Yvvv v^2 - Yrv|r|, d23 = -Yr - Yrr|r| - Yrrr r^2 - Yvr|v|,
        d32 = -Nv - Nvv|v| - Nvvv v^2 - Nrv|r|, d33 = -Nr - Nrr|r| - Nrrr r^2 - Nvr|v|.
        The lab's simulator file shifts some indices (apparently a bug); this is the
        usual form. Xvv is not part of it.
    """
    u, v, r = nu
    d11 = -XU - XUU * abs(u) - XUUU * u * u
    d22 = -YV - YVV * abs(v) - YVVV * v * v - YRV * abs(r)
    d23 = -YR - YRR * abs(r) - YRRR * r * r - YVR * abs(v)
    d32 = -NV - NVV * abs(v) - NVVV * v * v - NRV * abs(r)
    d33 = -NR - NRR * abs(r) - NRRR * r * r - NVR * abs(v)
    return np.array([[d11, 0.0, 0.0], [0.0, d22, d23], [0.0, d32, d33]])


def nu_dot(nu: FloatArray, tau: FloatArray) -> FloatArray:
    """Return M^-1 (tau - C(nu) nu - D(nu) nu), shape (3,)."""
    out: FloatArray = M_INV @ (tau - coriolis(nu) @ nu - damping(nu) @ nu)
    return out


def state_dot(x: FloatArray, tau: FloatArray) -> FloatArray:
    """Return d/dt of x = (north, east, psi, u, v, r) under thrust tau, shape (6,)."""
    psi = x[2]
    c, s = math.cos(psi), math.sin(psi)
    u, v, r = x[3], x[4], x[5]
    return np.concatenate([[c * u - s * v, s * u + c * v, r], nu_dot(x[3:6], tau)])


@dataclass
class Actuators:
    """What the thrusters deliver: the rate-limited wire values and the pod angles.

    Attributes:
        tunnel: Tunnel command (normalized).
        port: Port azimuth's commanded thrust vector (fx, fy), normalized.
        starboard: Starboard azimuth's commanded thrust vector, normalized.
        port_rad: Port pod angle (rad, 0 = thrust forward, +pi/2 = to starboard).
        starboard_rad: Starboard pod angle (rad).
    """

    tunnel: float = 0.0
    port: tuple[float, float] = (0.0, 0.0)
    starboard: tuple[float, float] = (0.0, 0.0)
    port_rad: float = PORT_REFERENCE_RAD
    starboard_rad: float = STARBOARD_REFERENCE_RAD


def _toward(now: float, target: float, step: float) -> float:
    return now + max(-step, min(step, target - now))


def _saturate_vector(xy: tuple[float, float]) -> tuple[float, float]:
    norm = math.hypot(*xy)
    return xy if norm <= 1.0 else (xy[0] / norm, xy[1] / norm)


def _pod_toward(angle_rad: float, xy: tuple[float, float], max_turn_rad: float) -> float:
    """Turn a pod toward the line of `xy` the short way (propeller reversed past 90 deg)."""
    if math.hypot(*xy) < 1e-9:
        return angle_rad
    target = math.atan2(xy[1], xy[0])
    error = wrap(target - angle_rad)
    if abs(error) > math.pi / 2:
        error = wrap(error + math.pi)
    return wrap(angle_rad + max(-max_turn_rad, min(max_turn_rad, error)))


def actuators_step(now: Actuators, tunnel: float, port: tuple[float, float],
                   starboard: tuple[float, float], dt_s: float,
                   azimuth_rate_radps: float) -> Actuators:
    """Move the actuators toward the wire commands over `dt_s` within their limits."""
    step = COMMAND_RATE_PER_S * dt_s
    port, starboard = _saturate_vector(port), _saturate_vector(starboard)
    new_port = (_toward(now.port[0], port[0], step), _toward(now.port[1], port[1], step))
    new_stbd = (_toward(now.starboard[0], starboard[0], step),
                _toward(now.starboard[1], starboard[1], step))
    if azimuth_rate_radps > 0.0:
        turn = azimuth_rate_radps * dt_s
        port_rad = _pod_toward(now.port_rad, new_port, turn)
        stbd_rad = _pod_toward(now.starboard_rad, new_stbd, turn)
    else:
        port_rad, stbd_rad = now.port_rad, now.starboard_rad
    limit = TUNNEL_LIMIT
    return Actuators(_toward(now.tunnel, max(-limit, min(limit, tunnel)), step),
                     new_port, new_stbd, port_rad, stbd_rad)


def thrust(act: Actuators, azimuth_rate_radps: float) -> FloatArray:
    """Return tau = (X N, Y N, N N m) the thrusters deliver, shape (3,)."""
    forces = [(TUNNEL_X_M, 0.0, 0.0, TUNNEL_GAIN_N * act.tunnel)]
    for (fx, fy), angle, ly in ((act.port, act.port_rad, PORT_Y_M),
                                (act.starboard, act.starboard_rad, STARBOARD_Y_M)):
        if azimuth_rate_radps > 0.0:
            # A pod pushes along its axis: the commanded vector's component there.
            along = fx * math.cos(angle) + fy * math.sin(angle)
            fx, fy = along * math.cos(angle), along * math.sin(angle)
        forces.append((AZIMUTH_X_M, ly, AZIMUTH_GAIN_N * fx, AZIMUTH_GAIN_N * fy))
    tau = np.zeros(3)
    for lx, ly, f_x, f_y in forces:
        tau += (f_x, f_y, lx * f_y - ly * f_x)
    return tau


def advance(x: FloatArray, tau0: FloatArray, tau1: FloatArray, dt_s: float) -> FloatArray:
    """Integrate the hull over one cycle, thrust ramping from tau0 to tau1 (RK45)."""
    def rhs(t: float, y: FloatArray) -> FloatArray:
        return state_dot(y, tau0 + (t / dt_s) * (tau1 - tau0))

    sol = solve_ivp(rhs, (0.0, dt_s), x, method="RK45", rtol=1e-9, atol=1e-11)
    if not sol.success:
        raise RuntimeError(f"the integrator failed: {sol.message}")
    out: FloatArray = sol.y[:, -1].copy()
    out[2] = wrap(float(out[2]))
    return out


def _triple(text: str) -> tuple[float, float, float]:
    parts = text.split(",")
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"expected three comma-separated numbers, got {text!r}")
    try:
        a, b, c = (float(p) for p in parts)
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"not numbers: {text!r}") from err
    if not all(math.isfinite(v) for v in (a, b, c)):
        raise argparse.ArgumentTypeError(f"not finite: {text!r}")
    return a, b, c


def _positive(text: str) -> float:
    value = float(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be positive, got {text!r}")
    return value


class Vessel:
    """The simulated hull, its thrusters and sensors behind the lab's ROS 2 topics."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        north, east, yaw_deg = args.start
        u, v, r_deg = args.start_velocity
        self.x = np.array([north, east, wrap(math.radians(yaw_deg)), u, v, math.radians(r_deg)])
        self.act = Actuators()
        self.azimuth_rate = math.radians(args.azimuth_rate_deg_s)
        self.rng = np.random.default_rng(args.seed)
        self.stop = threading.Event()
        self.stopped_by = ""
        self._lock = threading.Lock()
        self._wire: dict[str, tuple[float, float]] = {
            "tunnel": (0.0, 0.0), "port": (0.0, 0.0), "starboard": (0.0, 0.0)}
        self.commands = 0
        self.commanded = threading.Event()
        self.k = 0  # the physics cycle in progress (set by the loop)
        self.last_command_k = 0  # the cycle in which the latest command arrived

    def on_wrench(self, name: str, msg: Any) -> None:
        """Keep the latest normalized wrench of one thruster."""
        with self._lock:
            self._wire[name] = (float(msg.force.x), float(msg.force.y))
            self.commands += 1
            self.last_command_k = self.k
        self.commanded.set()

    def wire(self) -> tuple[float, tuple[float, float], tuple[float, float]]:
        """Return the latest (tunnel, port vector, starboard vector) commands."""
        with self._lock:
            return self._wire["tunnel"][0], self._wire["port"], self._wire["starboard"]

    def pose_message(self, msg_type: Any, t_ns: int) -> Any:
        """Return the mocap pose in world_ned with the configured noise."""
        msg = msg_type()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, NS_PER_S)
        msg.header.frame_id = "world_ned"
        sigma_m, sigma_rad = self.args.pose_noise_m, math.radians(self.args.pose_noise_deg)
        msg.pose.pose.position.x = float(self.x[0] + sigma_m * self.rng.standard_normal())
        msg.pose.pose.position.y = float(self.x[1] + sigma_m * self.rng.standard_normal())
        yaw = float(self.x[2] + sigma_rad * self.rng.standard_normal())
        q = msg.pose.pose.orientation  # a rotation about NED z (down): (x, y, z, w)
        q.x, q.y, q.z, q.w = 0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)
        return msg

    def imu_message(self, msg_type: Any, t_ns: int, tau: FloatArray) -> Any:
        """Return the IMU reading: body specific force (u_dot - r v, v_dot + r u) and r."""
        msg = msg_type()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, NS_PER_S)
        msg.header.frame_id = "voyager/imu_link"
        u, v, r = self.x[3:6]
        acc = nu_dot(self.x[3:6], tau)
        sa, sg = self.args.imu_accel_noise, math.radians(self.args.imu_gyro_noise_deg_s)
        msg.linear_acceleration.x = float(acc[0] - r * v + sa * self.rng.standard_normal())
        msg.linear_acceleration.y = float(acc[1] + r * u + sa * self.rng.standard_normal())
        # Gravity on the down axis of a level FRD body reads as -g of specific force.
        msg.linear_acceleration.z = -GRAVITY_MPS2
        msg.angular_velocity.z = float(r + sg * self.rng.standard_normal())
        msg.orientation_covariance[0] = -1.0  # REP 145: no orientation
        return msg


def run(args: argparse.Namespace) -> int:
    """Simulate and publish until the duration, SIGINT or SIGTERM; write the truth CSV."""
    try:
        import rclpy
        from geometry_msgs.msg import PoseWithCovarianceStamped, Wrench
        from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import Imu
    except ImportError as err:
        print(f"independent_vessel: needs rclpy and the ROS 2 message packages ({err})",
              file=sys.stderr)
        return 2
    vessel = Vessel(args)

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        vessel.stopped_by = signal.Signals(signum).name
        vessel.stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)

    context = rclpy.Context()
    rclpy.init(context=context, domain_id=args.domain_id)
    node = rclpy.create_node("independent_vessel", context=context)
    pose_pub = node.create_publisher(PoseWithCovarianceStamped, "/voyager/measurement/pose", 10)
    imu_pub = node.create_publisher(Imu, "/voyager/measurement/imu", 10)
    clock_pub = node.create_publisher(Clock, "/clock", 10) if args.clock else None
    for name in ("tunnel", "port", "starboard"):
        node.create_subscription(Wrench, f"/voyager/thruster/{name}/command",
                                 lambda msg, n=name: vessel.on_wrench(n, msg), 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)

    def spin() -> None:
        with contextlib.suppress(ExternalShutdownException):
            executor.spin()

    spinner = threading.Thread(target=spin, name="spin", daemon=True)
    spinner.start()

    def log(line: str) -> None:
        print(f"independent_vessel: {line}", file=sys.stderr, flush=True)

    def publish_clock(t_ns: int) -> None:
        if clock_pub is not None:
            msg = Clock()
            msg.clock.sec, msg.clock.nanosec = divmod(t_ns, NS_PER_S)
            clock_pub.publish(msg)

    pose_every = max(1, round(100.0 / args.pose_hz))
    lead_cycles = None if args.lockstep_s is None else max(1, round(args.lockstep_s * 100.0))
    imu_every = max(1, round(100.0 / args.imu_hz))
    clock_mode = f"/clock at {args.speed:g}x" if args.clock else "wall time"
    if lead_cycles is not None:
        clock_mode += f", lockstep {lead_cycles * CYCLE_NS / NS_PER_S:g} s"
    log(f"domain {args.domain_id}, {clock_mode}, start {tuple(args.start)} (world_ned, deg), "
        f"velocity {tuple(args.start_velocity)}, truth to {args.out}")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    rows = 0
    with out.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["t_ns", "north_m", "east_m", "yaw_rad", "u_mps", "v_mps", "r_radps"])
        # Held at the start until the stack commands (or at once): clock and pose frozen.
        if args.hold_until_commanded:
            log("holding at the start pose until the first thruster command")
            # In wall time the mocap keeps seeing the held hull: poses at their rate. On
            # a frozen clock, one pose per new subscriber (and a reminder every 5 s):
            # repeats of one stamp would only be refused as stale by the stack's filter.
            seen, next_reminder = 0, time.monotonic()
            wait_s = 0.1 if args.clock else 1.0 / args.pose_hz
            while not vessel.stop.is_set() and not vessel.commanded.wait(wait_s):
                if not args.clock:
                    pose_pub.publish(vessel.pose_message(PoseWithCovarianceStamped,
                                                         time.time_ns()))
                    continue
                publish_clock(0)
                subscribers = pose_pub.get_subscription_count()
                if subscribers > seen or time.monotonic() >= next_reminder:
                    seen, next_reminder = subscribers, time.monotonic() + 5.0
                    pose_pub.publish(vessel.pose_message(PoseWithCovarianceStamped, 0))
            log("released")
        t0_ns = 0 if args.clock else time.time_ns()
        k = behind = 0
        wall0 = time.monotonic()
        next_status = wall0 + 5.0
        tau = thrust(vessel.act, vessel.azimuth_rate)
        while not vessel.stop.is_set():
            t_ns = t0_ns + k * CYCLE_NS
            writer.writerow([t_ns, *(f"{float(v):.9g}" for v in vessel.x)])
            rows += 1
            if k % pose_every == 0:
                pose_pub.publish(vessel.pose_message(PoseWithCovarianceStamped, t_ns))
            if k % imu_every == 0:
                imu_pub.publish(vessel.imu_message(Imu, t_ns, tau))
            if args.duration is not None and k * CYCLE_NS >= args.duration * NS_PER_S:
                vessel.stopped_by = f"{args.duration:g} s simulated"
                break
            if lead_cycles is not None:
                # Lockstep: never run more than the lead past the stack's latest command,
                # so a starved stack sees a slower clock rather than late ticks.
                while (not vessel.stop.is_set()
                       and k - vessel.last_command_k >= lead_cycles):
                    time.sleep(0.0005)
            tunnel, port, starboard = vessel.wire()
            vessel.act = actuators_step(vessel.act, tunnel, port, starboard,
                                        CYCLE_NS / NS_PER_S, vessel.azimuth_rate)
            tau_next = thrust(vessel.act, vessel.azimuth_rate)
            vessel.x = advance(vessel.x, tau, tau_next, CYCLE_NS / NS_PER_S)
            tau = tau_next
            k += 1
            vessel.k = k
            publish_clock(t0_ns + k * CYCLE_NS)
            if time.monotonic() >= next_status:
                next_status += 5.0
                fh.flush()
                log(f"t={k * CYCLE_NS / NS_PER_S:6.1f} s  at ({vessel.x[0]:+.2f} N, "
                    f"{vessel.x[1]:+.2f} E, {math.degrees(vessel.x[2]):+.0f} deg)  "
                    f"thruster messages {vessel.commands}, pacing resets {behind}")
            # Pace: simulated time at `speed` x wall time (wall time: speed 1). Behind by
            # more than a cycle (this process starved of CPU), drop the debt instead of
            # racing to catch up: a burst of /clock would outrun the stack's loop.
            ahead_s = k * CYCLE_NS / NS_PER_S / args.speed - (time.monotonic() - wall0)
            if ahead_s > 0:
                time.sleep(ahead_s)
            elif args.clock and ahead_s < -CYCLE_NS / NS_PER_S:
                wall0 += ahead_s
                behind += 1
    log(f"stopped ({vessel.stopped_by or 'done'}): {rows} true states in {out}")
    executor.shutdown()
    node.destroy_node()
    context.try_shutdown()
    spinner.join(timeout=2.0)
    return 0


def main(argv: list[str] | None = None) -> int:
    """Parse the arguments and run."""
    parser = argparse.ArgumentParser(
        description="An independent C/S Voyager simulator on the lab's ROS 2 topics "
                    "(pose, IMU, thruster commands, optionally /clock); records its true state.")
    parser.add_argument("--start", type=_triple, default=(4.0, 0.0, 90.0), metavar="N,E,YAW_DEG",
                        help="start pose in world_ned: north m, east m, heading deg")
    parser.add_argument("--start-velocity", type=_triple, default=(0.0, 0.0, 0.0),
                        metavar="U,V,R_DEG_S", help="start body velocity: m/s, m/s, deg/s")
    parser.add_argument("--duration", type=_positive, default=None, metavar="S",
                        help="stop after this many simulated seconds from release")
    parser.add_argument("--domain-id", type=int, default=0, help="ROS_DOMAIN_ID")
    parser.add_argument("--out", type=Path, required=True, metavar="CSV",
                        help="true-state file to write")
    parser.add_argument("--clock", action="store_true", help="publish /clock (ROS sim time)")
    parser.add_argument("--speed", type=_positive, default=1.0,
                        help="simulated seconds per wall second (needs --clock above 1)")
    parser.add_argument("--lockstep-s", type=_positive, default=None, metavar="LEAD",
                        help="with --clock: run at most LEAD simulated seconds past the "
                             "latest thruster command (the clock waits for a slow stack)")
    parser.add_argument("--pose-hz", type=_positive, default=100.0, help="mocap pose rate")
    parser.add_argument("--imu-hz", type=_positive, default=100.0, help="IMU rate")
    parser.add_argument("--pose-noise-m", type=float, default=0.001)
    parser.add_argument("--pose-noise-deg", type=float, default=0.1)
    parser.add_argument("--imu-accel-noise", type=float, default=0.01, metavar="MPS2")
    parser.add_argument("--imu-gyro-noise-deg-s", type=float, default=0.05)
    parser.add_argument("--azimuth-rate-deg-s", type=float, default=0.0,
                        help="pod slew rate; 0: pods point at once")
    parser.add_argument("--seed", type=int, default=0, help="seed of the sensor noise")
    parser.add_argument("--no-hold", dest="hold_until_commanded", action="store_false",
                        help="run from the start instead of holding until the first command")
    args = parser.parse_args(argv)
    if args.speed != 1.0 and not args.clock:
        parser.error("--speed other than 1 needs --clock")
    if args.lockstep_s is not None and not args.clock:
        parser.error("--lockstep-s needs --clock (wall time cannot wait)")
    if not 0 <= args.domain_id <= 232:
        parser.error(f"--domain-id must be 0..232, got {args.domain_id!r}")
    return run(args)


if __name__ == "__main__":
    sys.exit(main())
