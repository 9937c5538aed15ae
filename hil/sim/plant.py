"""The simulated plant: thrusters and hull advanced together, one physics step at a time.

One kernel, :func:`plant_step`, holds the order of operations that both the
Python-level simulated world (:mod:`hil.adapters.sim`) and anything else that
steps the plant must share: the azimuth pods slew toward their setpoint (thrust
throttled while a pod still turns), the thrust acts on the hull with the
environmental load, and the hull integrates over `dt`.
"""

from __future__ import annotations

from hil.core.arrays import FloatArray
from hil.core.jit import njit
from hil.model.dynamics import Integrator, acceleration, euler_advance, integrate_step
from hil.model.thrusters import throttle_for_slew, thruster_force, thruster_update

_EULER = int(Integrator.EULER)  # a plain int: numba compiles the comparison as a constant

# Layout of a plant state row: pose, velocity, applied commands, azimuth angles.
P_ETA = 0
P_NU = 3
P_U = 6
P_ALPHA = 9
N_PLANT = 11

# Layout of a per-step trace row: time index, pose, velocity, acceleration, thrust.
TR_ETA = 0
TR_NU = 3
TR_NU_DOT = 6
TR_TAU = 9
N_TRACE = 12


@njit
def plant_step(
    m_inv: FloatArray,
    coef: FloatArray,
    tp: FloatArray,
    method: int,
    dt: float,
    state: FloatArray,
    u_set: FloatArray,
    alpha_set: FloatArray,
    b_env: FloatArray,
    trace_row: FloatArray,
) -> None:
    """Advance the plant one step of `dt` seconds in place.

    Args:
        m_inv: Vessel M^-1, shape (3, 3).
        coef: Vessel coefficient array.
        tp: Thruster parameter array.
        method: Integrator (:class:`hil.model.dynamics.Integrator` value).
        dt: Physics step (s).
        state: Plant state, shape (N_PLANT,), updated in place (see P_*).
        u_set: Commanded (tunnel, port, starboard), shape (3,), normalized.
        alpha_set: Commanded azimuth angles (port, starboard), shape (2,) (rad).
        b_env: Environmental load over this step, shape (3,) (N, N, N m).
        trace_row: Receives the state at the start of the step, shape (N_TRACE,):
            eta, nu, nu_dot (the accelerometer's truth) and the applied thrust tau.
    """
    # Views: the kernels below return new arrays and leave their inputs alone.
    eta = state[P_ETA : P_ETA + 3]
    nu = state[P_NU : P_NU + 3]
    a_now = state[P_ALPHA : P_ALPHA + 2]
    u_act, a_act = thruster_update(
        tp, state[P_U : P_U + 3], a_now, throttle_for_slew(u_set, alpha_set, a_now), alpha_set, dt
    )
    tau = thruster_force(tp, u_act, a_act)
    force = tau + b_env
    nu_dot = acceleration(m_inv, coef, nu, force)
    trace_row[TR_ETA : TR_ETA + 3] = eta
    trace_row[TR_NU : TR_NU + 3] = nu
    trace_row[TR_NU_DOT : TR_NU_DOT + 3] = nu_dot
    trace_row[TR_TAU : TR_TAU + 3] = tau
    if method == _EULER:  # reuse the accelerometer's nu_dot
        eta_new, nu_new = euler_advance(eta, nu, nu_dot, dt)
    else:
        eta_new, nu_new = integrate_step(m_inv, coef, eta, nu, force, dt, method)
    state[P_ETA : P_ETA + 3] = eta_new
    state[P_NU : P_NU + 3] = nu_new
    state[P_U : P_U + 3] = u_act
    state[P_ALPHA : P_ALPHA + 2] = a_act


@njit
def plant_advance(
    m_inv: FloatArray,
    coef: FloatArray,
    tp: FloatArray,
    method: int,
    dt: float,
    state: FloatArray,
    u_set: FloatArray,
    alpha_set: FloatArray,
    b_env: FloatArray,
    trace: FloatArray,
) -> None:
    """Advance `trace.shape[0]` steps with the command held; trace row k = step k's start.

    Args:
        m_inv: Vessel M^-1, shape (3, 3).
        coef: Vessel coefficient array.
        tp: Thruster parameter array.
        method: Integrator (:class:`hil.model.dynamics.Integrator` value).
        dt: Physics step (s).
        state: Plant state, shape (N_PLANT,), updated in place.
        u_set: Commanded (tunnel, port, starboard), shape (3,).
        alpha_set: Commanded azimuth angles, shape (2,) (rad).
        b_env: Environmental load per step, shape (n, 3).
        trace: Output, shape (n, N_TRACE).
    """
    for k in range(trace.shape[0]):
        plant_step(m_inv, coef, tp, method, dt, state, u_set, alpha_set, b_env[k], trace[k])
