"""The low level as one compiled tick: velocity PID -> thrust allocation -> PID integrator.

One ``@njit`` kernel, :func:`low_level_tick`, is the low level that the vessel runs
(through :class:`LowLevelController`, behind the runtime's ``LowLevel`` protocol) and
that the compiled closed loop of :mod:`hil.sim.closed_loop` calls at every control
period, so the benchmarks measure the code on the vessel. Per tick, on the estimate
``nu_hat`` and the reference ``nu_ref``:

1. :func:`~hil.controllers.pid.pid_command`: force demand tau (clipped) and tau_raw;
2. allocation of tau from the pod angles the thrusters have reached by their model
   (the vessel reports neither thrust nor pod angles): minimum magnitude and azimuth
   (:func:`~hil.controllers.allocation.mma_allocate`, which also advances the
   null-space parameter theta) or the plain pseudo-inverse;
3. the thrusters' model (:func:`hil.model.thrusters.thruster_update`: the documented
   command rate limit, the pod slew rate, thrust throttled while a pod turns) moves the
   modelled thruster state toward the commands over the tick;
4. :func:`~hil.controllers.pid.pid_integrate` with the force the modelled thrusters
   deliver: the integrator stops while the thrust is still ramping (without the model it
   wound up and overshot a 0.05 m/s surge step by 9.5 %).

All state lives in one array (``L_*`` layout): the PID state, theta (N) and the
modelled thruster commands and pod angles, so the kernel is pure and the closed loop
keeps the state as a plain array.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from hil.controllers.allocation import MmaArrays, MmaConfig
from hil.controllers.allocation_kernels import mma_allocate, pseudo_inverse_allocate
from hil.controllers.pid import (
    DEFAULT_GAINS,
    N_PID_STATE,
    PidConfigError,
    PidGains,
    checked_vec3,
    pid_command,
    pid_integrate,
)
from hil.core.arrays import FloatArray
from hil.core.jit import njit
from hil.model.coefficients import ENTERPRISE_I, VesselParams
from hil.model.thrusters import (
    VOYAGER_THRUSTERS,
    ThrusterParams,
    throttle_for_slew,
    thruster_force,
    thruster_update,
)

# Layout of the low-level state array.
L_PID = 0
L_THETA = N_PID_STATE
L_U_PRED = N_PID_STATE + 2  # commands the thrusters have reached (their model), (3,)
L_A_PRED = N_PID_STATE + 5  # angles the pods have reached (their model), (2,) rad
N_LOW_LEVEL_STATE = N_PID_STATE + 7


class AllocatorKind(enum.IntEnum):
    """Which allocator the low level runs; the value is what the kernel receives."""

    PSEUDO_INVERSE = 0
    MIN_MAGNITUDE_AZIMUTH = 1


_MMA = int(AllocatorKind.MIN_MAGNITUDE_AZIMUTH)  # a plain int: a constant in the kernel


class LowLevelArrays(NamedTuple):
    """The constant inputs of :func:`low_level_tick`; numba passes it as a tuple.

    Attributes:
        g: PID gain array, shape (N_GAINS,).
        m: Vessel inertia matrix M, shape (3, 3).
        coef: Vessel coefficient array (feed-forward).
        tp: Thruster parameter array.
        kind: :class:`AllocatorKind` value.
        be: Extended configuration matrix B_e, shape (3, 5).
        b_pinv: The allocator's (weighted) pseudo-inverse of B_e, shape (5, 3).
        q: Null-space basis of B_e, shape (5, 2).
        acfg: Allocator settings (gamma, lam, eps, dt, iterations, reg), shape (6,).
        a_ref: Reference thrust directions (port, starboard), unit rows, (2, 2).
        aw: Allocator cost weights, shape (3,).
        wq: Allocator residual weights, shape (3,).
        dt: Control period (s).
    """

    g: FloatArray
    m: FloatArray
    coef: FloatArray
    tp: FloatArray
    kind: int
    be: FloatArray
    b_pinv: FloatArray
    q: FloatArray
    acfg: FloatArray
    a_ref: FloatArray
    aw: FloatArray
    wq: FloatArray
    dt: float


@njit
def low_level_tick(
    a: LowLevelArrays, state: FloatArray, nu_ref: FloatArray, nu_hat: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Run one low-level tick; return ``(tau, u, alpha, tau_ach, state)``.

    Args:
        a: Constant arrays (gains, vessel, allocator).
        state: Low-level state, shape (N_LOW_LEVEL_STATE,), ``L_*`` layout; not modified.
        nu_ref: Velocity reference (u m/s, v m/s, r rad/s), shape (3,).
        nu_hat: Velocity estimate, same units, shape (3,).

    Returns:
        tau: Force demand within the PID's limits (X N, Y N, N N m), shape (3,).
        u: Thruster commands (tunnel, port, starboard), normalized, shape (3,).
        alpha: Pod angles (port, starboard) (rad), shape (2,).
        tau_ach: The force the thrusters deliver by the end of the tick, by their model
            (rate limits, pod slew, throttle while turning), shape (3,) (N, N, N m).
        state: The state after the tick, shape (N_LOW_LEVEL_STATE,).

    Notes:
        tau = PID(nu_ref, nu_hat); (u, alpha, xi, theta) = allocate(tau, theta,
        alpha_m); (u_m, alpha_m) <- thrusters(u_m, alpha_m -> u, alpha, dt); z <- z + dt
        (e' + Kaw (T(u_m, alpha_m) - tau_raw) / (Ki M_ii)), with e' = 0 while T misses
        tau_raw (conditional integration on the modelled thrust: Astrom & Hagglund 2006,
        Sec. 3.5, anti-windup with an actuator model). (u_m, alpha_m) is the thrusters'
        state by their model (:func:`hil.model.thrusters.thruster_update`); see
        :mod:`hil.controllers.allocation` (Gezer et al. 2024).
    """
    # Views of the input state: the kernels below return new arrays and leave it alone.
    theta = state[L_THETA : L_THETA + 2]
    # Allocate from where the pods are (modelled), turning them at most 90 deg from there.
    u_now = state[L_U_PRED : L_U_PRED + 3]
    a_now = state[L_A_PRED : L_A_PRED + 2]
    tau, tau_raw, s_pid = pid_command(
        a.g, a.m, a.coef, state[L_PID : L_PID + N_PID_STATE], nu_ref, nu_hat, a.dt
    )
    if a.kind == _MMA:
        u, alpha, _, theta_new = mma_allocate(
            a.tp, a.be, a.b_pinv, a.q, theta, tau, a_now, a.acfg, a.a_ref, a.aw, a.wq
        )
    else:
        u, alpha, _ = pseudo_inverse_allocate(a.tp, a.b_pinv, tau, a_now)
        theta_new = theta.copy()
    # The thrusters follow the commands within their rate limits (and throttle while a pod
    # turns): the integrator must see what they deliver, not what was asked, or it winds
    # up while the thrust ramps. The limits are the thrusters' documented ones, so the
    # model runs on the vessel too (it reports neither thrust nor pod angles).
    u_next, a_next = thruster_update(
        a.tp, u_now, a_now, throttle_for_slew(u, alpha, a_now), alpha, a.dt
    )
    tau_ach = thruster_force(a.tp, u_next, a_next)
    s_pid = pid_integrate(a.g, a.m, s_pid, nu_ref, nu_hat, tau_raw, tau_ach, a.dt)
    out = np.empty(N_LOW_LEVEL_STATE)
    out[L_PID : L_PID + N_PID_STATE] = s_pid
    out[L_THETA : L_THETA + 2] = theta_new
    out[L_U_PRED : L_U_PRED + 3] = u_next
    out[L_A_PRED : L_A_PRED + 2] = a_next
    return tau, u, alpha, tau_ach, out


@dataclass(frozen=True)
class LowLevelParams:
    """Everything that defines the low level.

    Attributes:
        gains: PID gains.
        vessel: Vessel model (inertia and feed-forward).
        thrusters: Thruster geometry and limits.
        allocator: Which allocator to run.
        mma: Settings of the minimum-magnitude-and-azimuth allocator (its ``dt_s`` is
            the period of its null-space descent; 0.05 s as the lab's).
        dt_s: Control period (s) of the PID; 0.05 s (20 Hz) as on the vessel.
    """

    gains: PidGains = DEFAULT_GAINS
    vessel: VesselParams = ENTERPRISE_I
    thrusters: ThrusterParams = VOYAGER_THRUSTERS
    allocator: AllocatorKind = AllocatorKind.MIN_MAGNITUDE_AZIMUTH
    mma: MmaConfig = field(default_factory=MmaConfig)
    dt_s: float = 0.05

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt_s) and self.dt_s > 0.0):
            raise PidConfigError(f"dt_s must be positive, got {self.dt_s!r}")

    def arrays(self) -> LowLevelArrays:
        """Return the kernel's constant arrays."""
        mma = MmaArrays.build(self.thrusters, self.mma)
        b_pinv = (
            mma.b_pinv
            if self.allocator is AllocatorKind.MIN_MAGNITUDE_AZIMUTH
            else np.ascontiguousarray(np.linalg.pinv(mma.be))
        )
        return LowLevelArrays(
            g=self.gains.as_array(self.thrusters),
            m=self.vessel.mass_matrix(),
            coef=self.vessel.kernel_arrays()[1],
            tp=mma.tp,
            kind=int(self.allocator),
            be=mma.be,
            b_pinv=b_pinv,
            q=mma.q,
            acfg=mma.cfg,
            a_ref=mma.a_ref,
            aw=mma.weights,
            wq=mma.wq,
            dt=float(self.dt_s),
        )

    def initial_state(self) -> FloatArray:
        """Return the state at rest, shape (N_LOW_LEVEL_STATE,).

        Integrator and filter zero, theta zero, pods held at the reference angles.
        """
        state = np.zeros(N_LOW_LEVEL_STATE)
        state[L_A_PRED : L_A_PRED + 2] = self.mma.reference_angles_rad
        return state


@dataclass(frozen=True, slots=True)
class LowLevelTick:
    """One tick of the low level.

    Attributes:
        tau_n: Force demand (X N, Y N, N N m), shape (3,).
        commands: Thruster commands (tunnel, port, starboard), normalized, shape (3,).
        angles_rad: Pod angles (port, starboard) (rad), shape (2,).
        achieved_n: The force the thrusters deliver by the end of the tick, by their model
            (N, N, N m), shape (3,).
    """

    tau_n: FloatArray
    commands: FloatArray
    angles_rad: FloatArray
    achieved_n: FloatArray


class LowLevelController:
    """The low level with its state: call :meth:`tick` once per control period.

    Args:
        params: Gains, models, allocator and period.
    """

    def __init__(self, params: LowLevelParams | None = None) -> None:
        self.params = LowLevelParams() if params is None else params
        self._arrays = self.params.arrays()
        self._state = self.params.initial_state()

    @property
    def state(self) -> FloatArray:
        """Return a copy of the state, shape (N_LOW_LEVEL_STATE,), ``L_*`` layout."""
        return self._state.copy()

    def reset(self) -> None:
        """Forget the integrator and filter, zero theta and the modelled thrust, pods at rest."""
        self._state = self.params.initial_state()

    def tick(self, nu_ref: FloatArray, nu_hat: FloatArray) -> LowLevelTick:
        """Return the demand and the commands for ``nu_ref`` and ``nu_hat``, shape (3,).

        Raises:
            NonFiniteInputError: If either holds NaN or inf; the state is unchanged.
        """
        ref = checked_vec3("nu_ref", nu_ref)
        est = checked_vec3("nu_hat", nu_hat)
        tau, u, alpha, ach, self._state = low_level_tick(self._arrays, self._state, ref, est)
        return LowLevelTick(tau, u, alpha, ach)
