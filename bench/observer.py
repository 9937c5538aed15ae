"""Cost of the EKF per 100 Hz step inside compiled code, against the bare math kernels.

`python -m bench observer [--seconds S] [--delay-steps D ...]`

Rows: the bare math kernels (predict + yaw-rate + pose update, no history: the
baseline), then the event kernels (`obs_imu` + `obs_pose`) with poses delivered
0, 2, 5 steps late, each from one compiled loop over a simulated run. Columns: us
per step, ratio to the baseline, and the real-time factor of the observer alone.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from hil.controllers.observer import ObserverConfig
from hil.controllers.observer_arrays import EkfArrays
from hil.controllers.observer_imu import obs_imu
from hil.controllers.observer_kernels import obs_init, obs_pose
from hil.controllers.observer_math import (
    P_GATE_GYRO,
    P_GATE_POSE,
    P_R_GYRO,
    P_R_PSI,
    P_R_X,
    P_R_Y,
    ekf_predict,
    ekf_update_pose,
    ekf_update_yaw_rate,
)
from hil.core.jit import njit

FloatArray = NDArray[np.float64]
DT_NS = 10_000_000


@njit
def _bare_loop(x: FloatArray, P: FloatArray, meas: FloatArray, prm: FloatArray) -> float:
    r_diag = np.empty(3)
    r_diag[0] = prm[P_R_X]
    r_diag[1] = prm[P_R_Y]
    r_diag[2] = prm[P_R_PSI]
    for i in range(meas.shape[0]):
        ekf_predict(x, P, 0.01, meas[i, 0], meas[i, 1], prm)
        ekf_update_yaw_rate(x, P, meas[i, 2], prm[P_R_GYRO], prm[P_GATE_GYRO])
        ekf_update_pose(x, P, meas[i, 3:6], r_diag, prm[P_GATE_POSE])
    return float(x[0])


@njit
def _event_loop(a: EkfArrays, meas: FloatArray, delay: int) -> float:
    for i in range(1, meas.shape[0]):
        obs_imu(a, i * DT_NS, meas[i, 0], meas[i, 1], meas[i, 2])
        j = i - delay
        if j >= 1:
            obs_pose(a, j * DT_NS, meas[j, 3], meas[j, 4], meas[j, 5])
    return float(a.x[0])


def _measurements(n: int) -> FloatArray:
    rng = np.random.default_rng(0)
    t = np.arange(n) * 0.01
    meas = np.zeros((n, 6))
    meas[:, 0] = 0.02 * np.cos(0.5 * t) + rng.normal(size=n) * 0.012
    meas[:, 1] = rng.normal(size=n) * 0.012
    meas[:, 2] = 0.05 + rng.normal(size=n) * 0.0017
    # A slow circle: u = 0.1 m/s, r = 0.05 rad/s.
    meas[:, 3] = 2.0 * np.sin(0.05 * t) + rng.normal(size=n) * 0.001
    meas[:, 4] = 2.0 * (1 - np.cos(0.05 * t)) + rng.normal(size=n) * 0.001
    meas[:, 5] = np.remainder(0.05 * t + np.pi, 2 * np.pi) - np.pi
    return meas


def _best_of(run: Callable[[], None], setup: Callable[[], None], repeats: int) -> float:
    """Return the shortest wall time of `run` over `repeats` tries, `setup` untimed before each."""
    best = math.inf
    for _ in range(repeats):
        setup()
        t0 = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - t0)
    return best


def main(argv: list[str] | None = None) -> int:
    """Print the per-step cost table."""
    parser = argparse.ArgumentParser(prog="bench observer", description=__doc__)
    parser.add_argument("--seconds", type=float, default=180.0, help="simulated run length")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--delay-steps", type=int, nargs="+", default=[0, 2, 5])
    args = parser.parse_args(argv)
    n = int(args.seconds * 100)
    meas = _measurements(n)
    cfg = ObserverConfig()
    prm = cfg.params()

    def fresh() -> EkfArrays:
        a = cfg.arrays()
        x0 = np.zeros(9)
        x0[3] = 0.1
        obs_init(a, 0, x0, cfg.initial_covariance())
        return a

    # Compile (or load from cache) before timing.
    _bare_loop(np.zeros(9), cfg.initial_covariance(), meas[:10], prm)
    _event_loop(fresh(), meas[:10], 0)

    state: dict[str, EkfArrays] = {}

    def bare() -> None:
        _bare_loop(np.zeros(9), cfg.initial_covariance(), meas, prm)

    def no_setup() -> None:
        pass

    def setup() -> None:
        state["a"] = fresh()

    rows = [("bare kernels (baseline)", _best_of(bare, no_setup, args.repeats))]
    for delay in args.delay_steps:

        def event(d: int = delay) -> None:
            _event_loop(state["a"], meas, d)

        name = f"obs_imu + obs_pose, poses {delay} steps late"
        rows.append((name, _best_of(event, setup, args.repeats)))
    base = rows[0][1]
    print(
        f"EKF cost per 100 Hz step over {args.seconds:g} s simulated ({n} steps), best of "
        f"{args.repeats}"
    )
    print(f"{'variant':<40} {'us/step':>9} {'x baseline':>11} {'x real time':>12}")
    for name, secs in rows:
        per_step = secs / n * 1e6
        print(f"{name:<40} {per_step:9.3f} {secs / base:11.2f} {args.seconds / secs:12.0f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
