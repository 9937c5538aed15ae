"""Thrusters of the C/S Voyager: bow tunnel plus two azimuths, ``tau = B(alpha) K u``.

Commands ``u = (tunnel, port, starboard)`` are normalized to [-1, 1] (the tunnel
saturates at 0.7); the azimuth angles ``alpha = (port, starboard)`` are in radians in
the body frame (0 = thrust forward, +pi/2 = thrust to starboard). Commands and angles
are rate limited: the lab limits a command change to 0.1 per 20-Hz step (2 per second);
the azimuth slew rate is ours (see :class:`ThrusterParams`).

The math lives in ``@njit`` kernels on a parameter array built by
:meth:`ThrusterParams.as_array` (layout given by the ``T_*`` constants), shared by
:class:`Thrusters`, the allocators and the closed loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hil.core.arrays import FloatArray, finite_vector
from hil.core.geometry import wrap_angle
from hil.core.jit import njit
from hil.model.errors import NonFiniteCommandError, StateShapeError, VesselConfigError

# Layout of the thruster parameter array.
T_LX_TUNNEL = 0
T_LY_TUNNEL = 1
T_LX_PORT = 2
T_LY_PORT = 3
T_LX_STBD = 4
T_LY_STBD = 5
T_K_TUNNEL = 6
T_K_PORT = 7
T_K_STBD = 8
T_UMAX_TUNNEL = 9
T_UMAX_PORT = 10
T_UMAX_STBD = 11
T_CMD_RATE = 12
T_AZ_RATE = 13
N_THRUSTER_PARAMS = 14


@dataclass(frozen=True, slots=True)
class ThrusterParams:
    """Thruster geometry, gains and limits (body frame, x forward, y starboard).

    Attributes:
        tunnel_xy_m: Bow tunnel position (m); it thrusts along body y.
        port_xy_m: Port azimuth position (m).
        starboard_xy_m: Starboard azimuth position (m).
        gains_n: Thrust per unit command K = (tunnel, port, starboard) (N).
        tunnel_limit: Saturation of the tunnel command (normalized).
        command_rate_per_s: Largest change of a command per second (lab: 0.1 per
            20-Hz step = 2 /s).
        azimuth_rate_radps: Largest azimuth slew rate (rad/s). Ours: pi rad/s
            (180 deg/s); the lab publishes none. Servo-driven azimuths of ~1-m models
            turn 60 deg in roughly 0.2-0.4 s, so 150-300 deg/s is the plausible range.
    """

    tunnel_xy_m: tuple[float, float] = (0.3875, 0.0)
    port_xy_m: tuple[float, float] = (-0.4574, -0.055)
    starboard_xy_m: tuple[float, float] = (-0.4574, 0.055)
    gains_n: tuple[float, float, float] = (2.629, 1.03, 1.03)
    tunnel_limit: float = 0.7
    command_rate_per_s: float = 2.0
    azimuth_rate_radps: float = math.pi

    def __post_init__(self) -> None:
        arr = self.as_array()
        if not np.all(np.isfinite(arr)):
            raise VesselConfigError(f"thruster parameters must be finite, got {self!r}")
        if any(k <= 0.0 for k in self.gains_n):
            raise VesselConfigError(f"thrust gains must be positive, got {self.gains_n!r}")
        if not 0.0 < self.tunnel_limit <= 1.0:
            raise VesselConfigError(f"tunnel_limit must be in (0, 1], got {self.tunnel_limit!r}")
        if self.command_rate_per_s <= 0.0 or self.azimuth_rate_radps <= 0.0:
            raise VesselConfigError(
                f"rate limits must be positive, got {self.command_rate_per_s!r}, "
                f"{self.azimuth_rate_radps!r}"
            )

    def as_array(self) -> FloatArray:
        """Return the kernel parameter array, shape (N_THRUSTER_PARAMS,)."""
        return np.array(
            [
                *self.tunnel_xy_m,
                *self.port_xy_m,
                *self.starboard_xy_m,
                *self.gains_n,
                self.tunnel_limit,
                1.0,
                1.0,
                self.command_rate_per_s,
                self.azimuth_rate_radps,
            ],
            dtype=np.float64,
        )

    def max_thrust_n(self) -> FloatArray:
        """Return the largest thrust of each thruster (tunnel, port, starboard), (3,) (N)."""
        arr = self.as_array()
        return arr[T_K_TUNNEL : T_K_STBD + 1] * arr[T_UMAX_TUNNEL : T_UMAX_STBD + 1]


VOYAGER_THRUSTERS = ThrusterParams()
"""The C/S Voyager's thrusters with the published gains."""


@njit
def thrust_column(tp: FloatArray, j: int, alpha: FloatArray) -> tuple[float, float, float]:
    """Return column j of B(alpha) (0 tunnel, 1 port, 2 starboard) as three scalars.

    Notes:
        Column for angle a at (lx, ly): [cos a, sin a, lx sin a - ly cos a]; the tunnel
        is fixed at a = pi/2 (VESSEL.md; Fossen 2021, Sec. 11.2).
    """
    if j == 0:
        return 0.0, 1.0, tp[T_LX_TUNNEL]  # a = pi/2: the ly cos(a) term vanishes
    c = math.cos(alpha[j - 1])
    s = math.sin(alpha[j - 1])
    lx = tp[T_LX_PORT + 2 * (j - 1)]
    ly = tp[T_LY_PORT + 2 * (j - 1)]
    return c, s, lx * s - ly * c


@njit
def thrust_matrix(tp: FloatArray, alpha: FloatArray) -> FloatArray:
    """Return B(alpha), shape (3, 3): columns tunnel, port, starboard."""
    out = np.empty((3, 3))
    for j in range(3):
        out[0, j], out[1, j], out[2, j] = thrust_column(tp, j, alpha)
    return out


@njit
def thruster_force(tp: FloatArray, u: FloatArray, alpha: FloatArray) -> FloatArray:
    """Return tau = B(alpha) K u, shape (3,) (N, N, N m), for commands u (3,)."""
    out = np.zeros(3)
    for j in range(3):
        f = tp[T_K_TUNNEL + j] * u[j]
        bx, by, bn = thrust_column(tp, j, alpha)
        out[0] += bx * f
        out[1] += by * f
        out[2] += bn * f
    return out


@njit
def rate_limit(current: float, target: float, max_step: float) -> float:
    """Return ``target`` moved from ``current`` by at most ``max_step``."""
    if target > current + max_step:
        return current + max_step
    if target < current - max_step:
        return current - max_step
    return target


@njit
def thruster_update(
    tp: FloatArray,
    u_now: FloatArray,
    alpha_now: FloatArray,
    u_cmd: FloatArray,
    alpha_cmd: FloatArray,
    dt: float,
) -> tuple[FloatArray, FloatArray]:
    """Apply saturation and rate limits over ``dt`` seconds; return new ``(u, alpha)``.

    Commands are clipped to their limits (tunnel 0.7, azimuths 1) and then moved toward
    the target by at most ``command_rate * dt``; each azimuth turns the short way round
    by at most ``azimuth_rate * dt``; angles stay wrapped to [-pi, pi).
    """
    u_new = np.empty(3)
    for j in range(3):
        lim = tp[T_UMAX_TUNNEL + j]
        target = min(max(u_cmd[j], -lim), lim)
        u_new[j] = rate_limit(u_now[j], target, tp[T_CMD_RATE] * dt)
    a_new = np.empty(2)
    for j in range(2):
        diff = wrap_angle(alpha_cmd[j] - alpha_now[j])
        step = rate_limit(0.0, diff, tp[T_AZ_RATE] * dt)
        a_new[j] = wrap_angle(alpha_now[j] + step)
    return u_new, a_new


def _vec(name: str, value: object, n: int) -> FloatArray:
    return finite_vector(name, value, n, StateShapeError, NonFiniteCommandError)


@dataclass(frozen=True, slots=True)
class ThrusterState:
    """Commands and azimuth angles (applied, or a setpoint for :meth:`Thrusters.step`).

    Attributes:
        commands: (tunnel, port, starboard), shape (3,), normalized.
        angles_rad: (port, starboard) azimuth angles, shape (2,) (rad).
    """

    commands: FloatArray
    angles_rad: FloatArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "commands", _vec("commands", self.commands, 3))
        object.__setattr__(self, "angles_rad", _vec("angles_rad", self.angles_rad, 2))

    @staticmethod
    def idle(port_rad: float = math.pi / 2, starboard_rad: float = -math.pi / 2) -> ThrusterState:
        """Return zero commands with the azimuths at the given angles (default: reference)."""
        return ThrusterState(np.zeros(3), np.array([port_rad, starboard_rad]))


@dataclass(frozen=True)
class Thrusters:
    """The thruster set: limits, rate limits and the force it produces.

    Attributes:
        params: Geometry, gains and limits.
    """

    params: ThrusterParams = VOYAGER_THRUSTERS
    _tp: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_tp", self.params.as_array())

    def force(self, state: ThrusterState) -> FloatArray:
        """Return tau = B(alpha) K u, shape (3,) (N, N, N m), for an applied state."""
        return thruster_force(self._tp, state.commands, state.angles_rad)

    def step(self, state: ThrusterState, setpoint: ThrusterState, dt_s: float) -> ThrusterState:
        """Move the applied ``state`` toward ``setpoint`` over ``dt_s`` within all limits.

        Raises:
            NonFiniteCommandError: If the setpoint holds NaN or inf (at construction).
            VesselConfigError: If ``dt_s`` is not positive.
        """
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise VesselConfigError(f"dt_s must be positive, got {dt_s!r}")
        u, a = thruster_update(
            self._tp,
            state.commands,
            state.angles_rad,
            setpoint.commands,
            setpoint.angles_rad,
            dt_s,
        )
        return ThrusterState(u, a)


@njit
def throttle_for_slew(
    u_set: FloatArray, alpha_set: FloatArray, alpha_now: FloatArray
) -> FloatArray:
    """Return azimuth commands scaled by max(cos(alpha_set - alpha_now), 0), shape (3,).

    While a pod still turns toward its setpoint, full thrust would push in the wrong
    direction; scaling by the cosine of the angle error delivers only the component
    along the wanted direction (the tunnel, index 0, is unchanged).
    """
    out = u_set.copy()
    for j in range(2):
        c = math.cos(alpha_set[j] - alpha_now[j])
        out[1 + j] = u_set[1 + j] * max(c, 0.0)
    return out
