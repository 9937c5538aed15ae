"""MIMO PID velocity controller over (u, v, r) with model feed-forward and anti-windup.

The law (acting in acceleration units, scaled by the inertia matrix):

    e       = nu_ref - nu_hat
    tau_raw = n(nu_ref) + M (sat_j(Kp e) + Ki z - Kd d/dt nu_hat)
    tau     = clip(tau_raw, -tau_max, tau_max)
    z_dot   = e' + Kaw (tau_ach - tau_raw) / (Ki diag(M))       (back-calculation)

where e' = 0 while the achieved force misses the demand by more than a tolerance
(conditional integration), else e; n(nu) = C(nu) nu + D(nu) nu is the force that holds nu
steady (the vessel model's own :func:`hil.model.dynamics.hydro_force` kernel), tau_max
the thrust envelope per axis, tau_ach the force actually achieved (Astrom & Hagglund
2006, Sec. 3.5, back-calculation and conditional integration; Fossen 2021, Sec. 12.2,
feed-forward of the model). The derivative acts on the measurement through a
first-order filter so a step in nu_ref gives no kick; sat_j optionally caps the
proportional term at the braking curve sqrt(2 j |e|) (see :attr:`PidGains.brake_jerk`).

The math is in ``@njit`` kernels on plain arrays; :class:`VelocityPid` and the
low-level tick (:mod:`hil.controllers.low_level`, which the runtime and the closed
loop run) call the same ones.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hil.controllers.allocation_kernels import matvec
from hil.controllers.envelope import axis_force_limits
from hil.core.arrays import FloatArray, finite_vector
from hil.core.jit import njit
from hil.model.coefficients import ENTERPRISE_I, VesselParams
from hil.model.dynamics import hydro_force
from hil.model.thrusters import VOYAGER_THRUSTERS, ThrusterParams

# Layout of the gain array.
G_KP = 0
G_KI = 3
G_KD = 6
G_KAW = 9
G_TAU_MAX = 12
G_FF_ON = 15
G_D_TC = 16
G_BRAKE = 17
G_AW_ON = 20
G_AW_TOL = 21
N_GAINS = 22

# Layout of the controller state array.
S_Z = 0
S_DFILT = 3
S_NU_PREV = 6
S_STARTED = 9
N_PID_STATE = 10


class PidError(ValueError):
    """Base class of velocity-controller errors."""


class PidConfigError(PidError):
    """Invalid gains or limits."""


class NonFiniteInputError(PidError):
    """A reference or velocity estimate that holds NaN or inf."""


@dataclass(frozen=True, slots=True)
class PidGains:
    """Gains of the velocity PID, per axis (surge, sway, yaw rate).

    The gains act in acceleration units and are multiplied by M, so they read as
    closed-loop rates independent of the vessel's inertia.

    Attributes:
        kp_per_s: Proportional gains (1/s).
        ki_per_s2: Integral gains (1/s^2).
        kd: Derivative gains on the measured velocity (dimensionless).
        kaw: Back-calculation anti-windup gains (dimensionless, ~1).
        derivative_tc_s: Time constant of the derivative filter (s).
        feedforward: Add n(nu_ref) = C(nu_ref) nu_ref + D(nu_ref) nu_ref.
        brake_jerk: Per axis j (m/s^3, m/s^3, rad/s^3), or 0 for a plain P term: the
            proportional acceleration is capped at sqrt(2 j |e|), the braking curve
            of an error driven by an acceleration that can change at rate j. It lets
            a large error get the full thrust and still stop without overshoot when
            the thrust ramps slowly (rate limits).
        anti_windup: False turns off conditional integration and back-calculation.
        integrate_tolerance: The error is integrated only while the achieved force is
            within this fraction of (1 N + |demand|) of the demand.
        tau_max_n: Output limits (|X| N, |Y| N, |N| N m); None takes the thrusters'
            per-axis envelope.
    """

    kp_per_s: tuple[float, float, float] = (5.0, 4.0, 8.0)
    ki_per_s2: tuple[float, float, float] = (1.0, 1.0, 2.0)
    kd: tuple[float, float, float] = (0.0, 0.0, 0.0)
    # Back-calculation off: while a large error saturates the P term, it drives the
    # integrator to cancel P, and that bias lingers after the error is gone (measured
    # in the windup test of tests/controllers/test_pid.py: -0.43 m/s undershoot at
    # kaw = 0.1); conditional integration alone keeps the integrator clean.
    kaw: tuple[float, float, float] = (0.0, 0.0, 0.0)
    derivative_tc_s: float = 0.1
    feedforward: bool = True
    # Half the rate at which idle thrusters can build acceleration on each axis
    # (0.256 m/s^3, 0.389 m/s^3, 1.42 rad/s^3 from the command rate limit of 2 /s).
    brake_jerk: tuple[float, float, float] = (0.128, 0.195, 0.71)
    anti_windup: bool = True
    integrate_tolerance: float = 0.05
    tau_max_n: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        groups = {
            "kp_per_s": self.kp_per_s,
            "ki_per_s2": self.ki_per_s2,
            "kd": self.kd,
            "kaw": self.kaw,
            "brake_jerk": self.brake_jerk,
        }
        if self.tau_max_n is not None:
            groups["tau_max_n"] = self.tau_max_n
        for name, value in groups.items():
            if len(value) != 3 or not all(math.isfinite(v) and v >= 0.0 for v in value):
                raise PidConfigError(f"{name} must be 3 finite non-negative numbers, got {value!r}")
        if self.tau_max_n is not None and min(self.tau_max_n) <= 0.0:
            raise PidConfigError(f"tau_max_n must be positive, got {self.tau_max_n!r}")
        if not (math.isfinite(self.derivative_tc_s) and self.derivative_tc_s > 0.0):
            raise PidConfigError(f"derivative_tc_s must be positive, got {self.derivative_tc_s!r}")

    def as_array(self, thrusters: ThrusterParams = VOYAGER_THRUSTERS) -> FloatArray:
        """Return the kernel gain array, shape (N_GAINS,)."""
        tau_max = (
            axis_force_limits(thrusters)
            if self.tau_max_n is None
            else np.asarray(self.tau_max_n, dtype=np.float64)
        )
        return np.concatenate(
            [
                np.asarray(self.kp_per_s, dtype=np.float64),
                np.asarray(self.ki_per_s2, dtype=np.float64),
                np.asarray(self.kd, dtype=np.float64),
                np.asarray(self.kaw, dtype=np.float64),
                tau_max,
                [1.0 if self.feedforward else 0.0, self.derivative_tc_s],
                np.asarray(self.brake_jerk, dtype=np.float64),
                [1.0 if self.anti_windup else 0.0, self.integrate_tolerance],
            ]
        )


DEFAULT_GAINS = PidGains()
"""Gains tuned on the simulated vessel. Under the vessel's low level
(:mod:`hil.controllers.low_level`, true velocity fed back) single-axis grid steps settle
to 5 % by 1.5 s with under 5 % overshoot (tests/controllers/test_pid.py); the anti-windup
sees the thrust the thrusters deliver while it ramps, without which the smallest steps
overshot by 9.5 % (bench/lowlevel.py)."""


@njit
def pid_command(
    g: FloatArray,
    m: FloatArray,
    coef: FloatArray,
    s: FloatArray,
    nu_ref: FloatArray,
    nu_hat: FloatArray,
    dt: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Compute the force demand; return ``(tau_cmd, tau_raw, state)``, (3,), (3,), (10,).

    Args:
        g: Gain array, shape (N_GAINS,).
        m: Inertia matrix M, shape (3, 3).
        coef: Vessel coefficient array (for the feed-forward).
        s: Controller state, shape (N_PID_STATE,); not modified.
        nu_ref: Reference (u, v, r), shape (3,).
        nu_hat: Estimated velocity, shape (3,).
        dt: Controller period (s).
    """
    s_new = s.copy()
    if s[S_STARTED] == 0.0:
        for i in range(3):
            s_new[S_NU_PREV + i] = nu_hat[i]
            s_new[S_DFILT + i] = 0.0
        s_new[S_STARTED] = 1.0
    a = dt / (g[G_D_TC] + dt)
    acc = np.empty(3)
    for i in range(3):
        raw_d = (nu_hat[i] - s_new[S_NU_PREV + i]) / dt
        s_new[S_DFILT + i] += a * (raw_d - s_new[S_DFILT + i])
        s_new[S_NU_PREV + i] = nu_hat[i]
        e = nu_ref[i] - nu_hat[i]
        p_term = g[G_KP + i] * e
        brake = g[G_BRAKE + i]
        if brake > 0.0:
            # Time-optimal braking curve of e'' = -jerk: no more than sqrt(2 j |e|).
            cap = math.sqrt(2.0 * brake * abs(e))
            p_term = min(max(p_term, -cap), cap)
        acc[i] = p_term + g[G_KI + i] * s[S_Z + i] - g[G_KD + i] * s_new[S_DFILT + i]
    tau_raw = matvec(m, acc)
    if g[G_FF_ON] != 0.0:
        tau_raw += hydro_force(coef, nu_ref)
    tau = np.empty(3)
    for i in range(3):
        lim = g[G_TAU_MAX + i]
        tau[i] = min(max(tau_raw[i], -lim), lim)
    return tau, tau_raw, s_new


@njit
def pid_integrate(
    g: FloatArray,
    m: FloatArray,
    s: FloatArray,
    nu_ref: FloatArray,
    nu_hat: FloatArray,
    tau_raw: FloatArray,
    tau_ach: FloatArray,
    dt: float,
) -> FloatArray:
    """Advance the integrator with back-calculation; return the new state (10,).

    ``tau_ach`` is what was actually realized (the allocator's achieved force, or
    the clipped command), so the integrator stops winding as soon as saturation
    takes away authority on an axis.
    """
    s_new = s.copy()
    for i in range(3):
        ki = g[G_KI + i]
        if ki <= 0.0:
            continue
        e = nu_ref[i] - nu_hat[i]
        if g[G_AW_ON] == 0.0:
            s_new[S_Z + i] += dt * e
            continue
        short = tau_ach[i] - tau_raw[i]
        # Conditional integration: while the thrusters do not deliver the demand
        # (saturated, or still ramping at their rate limits), the error says more about
        # the actuators than about a model bias, so it is not integrated.
        if abs(short) > g[G_AW_TOL] * (1.0 + abs(tau_raw[i])):
            e = 0.0
        back = g[G_KAW + i] * short / (ki * m[i, i])
        s_new[S_Z + i] += dt * (e + back)
    return s_new


@dataclass(frozen=True, slots=True)
class PidOutput:
    """One controller output.

    Attributes:
        tau_n: Force demand within the limits (X N, Y N, N N m), shape (3,).
        tau_raw_n: The demand before the limits, shape (3,).
    """

    tau_n: FloatArray
    tau_raw_n: FloatArray


def checked_vec3(name: str, value: FloatArray) -> FloatArray:
    """Return `value` as a float array of shape (3,), or raise naming `name`.

    Raises:
        PidConfigError: Wrong shape.
        NonFiniteInputError: NaN or inf in it.
    """
    return finite_vector(name, value, 3, PidConfigError, NonFiniteInputError)


class VelocityPid:
    """The velocity controller with its state (integrator, derivative filter).

    Call :meth:`command` once per period, allocate, then :meth:`update` with the force
    the allocator achieved.
    """

    def __init__(
        self,
        gains: PidGains = DEFAULT_GAINS,
        vessel: VesselParams = ENTERPRISE_I,
        thrusters: ThrusterParams = VOYAGER_THRUSTERS,
        dt_s: float = 0.05,
    ) -> None:
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise PidConfigError(f"dt_s must be positive, got {dt_s!r}")
        self.gains = gains
        self.dt_s = dt_s
        self._g = gains.as_array(thrusters)
        self._m = vessel.mass_matrix()
        self._coef = vessel.kernel_arrays()[1]
        self._s = np.zeros(N_PID_STATE)

    @property
    def integrator(self) -> FloatArray:
        """Return the integrator state z, shape (3,) (m, m, rad)."""
        return self._s[S_Z : S_Z + 3].copy()

    def reset(self) -> None:
        """Zero the integrator and the derivative filter."""
        self._s = np.zeros(N_PID_STATE)

    def command(self, nu_ref: FloatArray, nu_hat: FloatArray) -> PidOutput:
        """Return the force demand for reference ``nu_ref`` and estimate ``nu_hat``, (3,).

        Raises:
            NonFiniteInputError: If either holds NaN or inf; the state is unchanged.
        """
        ref = checked_vec3("nu_ref", nu_ref)
        est = checked_vec3("nu_hat", nu_hat)
        tau, raw, self._s = pid_command(self._g, self._m, self._coef, self._s, ref, est, self.dt_s)
        return PidOutput(tau, raw)

    def update(
        self, nu_ref: FloatArray, nu_hat: FloatArray, output: PidOutput, tau_achieved: FloatArray
    ) -> None:
        """Advance the integrator given the force actually achieved, shape (3,)."""
        ref = checked_vec3("nu_ref", nu_ref)
        est = checked_vec3("nu_hat", nu_hat)
        ach = checked_vec3("tau_achieved", tau_achieved)
        self._s = pid_integrate(
            self._g, self._m, self._s, ref, est, output.tau_raw_n, ach, self.dt_s
        )
