"""Tests of the EKF state observer: kernels against numpy twins, closed forms, consistency."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg as sl  # type: ignore[import-untyped]
from scipy import stats

from hil.controllers.errors import (
    ObserverConfigError,
    ObserverInputError,
    ObserverNotInitializedError,
)
from hil.controllers.observer import Ekf, ObserverConfig, ObserverStatus
from hil.controllers.observer_arrays import (
    C_GYRO_GATED,
    C_IMU_ABSURD,
    C_IMU_FUSED,
    C_IMU_LATE,
    C_IMU_NONFINITE,
    C_POSE_ABSURD,
    C_POSE_FUSED,
    C_POSE_GATED,
    C_POSE_LATE,
    C_POSE_NONFINITE,
    C_POSE_RESET,
    C_POSE_TOO_OLD,
    S_ABSURD,
    S_DUPLICATE,
    S_FUSED,
    S_GATED,
    S_NONFINITE,
    S_RESET,
    S_TOO_OLD,
    EkfArrays,
)
from hil.controllers.observer_imu import obs_imu
from hil.controllers.observer_kernels import obs_init, obs_pose, obs_time_ns
from hil.controllers.observer_math import (
    P_Q_BA,
    P_Q_BR,
    P_Q_R,
    P_Q_UV,
    P_R_GYRO,
    P_R_PSI,
    P_R_X,
    P_R_Y,
    ekf_predict,
    ekf_update_pose,
    ekf_update_yaw_rate,
    pose_innovation,
)
from hil.controllers.observer_ring import M_GATED_RUN
from hil.core.arrays import FloatArray
from hil.core.samples import Frame, ImuSample, PoseSample

DT = 0.01
DT_NS = 10_000_000


# ---------------------------------------------------------------------------
# numpy twins of the kernels
# ---------------------------------------------------------------------------


def twin_jacobian(x: FloatArray) -> FloatArray:
    psi, u, v, r = x[2], x[3], x[4], x[5]
    c, s = math.cos(psi), math.sin(psi)
    J = np.zeros((9, 9))
    J[0, 2], J[0, 3], J[0, 4] = -s * u - c * v, c, -s
    J[1, 2], J[1, 3], J[1, 4] = c * u - s * v, s, c
    J[2, 5] = 1.0
    J[3, 4], J[3, 5], J[3, 6] = r, v, -1.0
    J[4, 3], J[4, 5], J[4, 7] = -r, -u, -1.0
    return J


def twin_predict(
    x: FloatArray, P: FloatArray, dt: float, ax: float, ay: float, prm: FloatArray
) -> tuple[FloatArray, FloatArray]:
    F = np.eye(9) + dt * twin_jacobian(x)
    q = [0, 0, 0, prm[P_Q_UV], prm[P_Q_UV], prm[P_Q_R]]
    Q = np.diag([*q, prm[P_Q_BA], prm[P_Q_BA], prm[P_Q_BR]]) * dt
    psi, u, v, r = x[2], x[3], x[4], x[5]
    xn = x.copy()
    xn[0] += dt * (math.cos(psi) * u - math.sin(psi) * v)
    xn[1] += dt * (math.sin(psi) * u + math.cos(psi) * v)
    xn[2] = math.remainder(psi + dt * r, 2 * math.pi)
    xn[3] += dt * (ax - x[6] + r * v)
    xn[4] += dt * (ay - x[7] - r * u)
    return xn, F @ P @ F.T + Q


def twin_update(
    x: FloatArray, P: FloatArray, H: FloatArray, y: FloatArray, R: FloatArray
) -> tuple[FloatArray, FloatArray, float]:
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    d2 = float(y @ np.linalg.solve(S, y))
    I_KH = np.eye(9) - K @ H
    # Joseph form: a different route to the same posterior covariance.
    return x + K @ y, I_KH @ P @ I_KH.T + K @ R @ K.T, d2


def random_state(rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
    x = rng.normal(size=9) * np.array([2, 2, 1, 0.2, 0.1, 0.2, 0.05, 0.05, 0.01])
    A = rng.normal(size=(9, 9)) * 0.05
    return x, A @ A.T + np.diag(rng.uniform(1e-4, 1e-2, 9))


def params(cfg: ObserverConfig | None = None) -> FloatArray:
    return (cfg or ObserverConfig()).params()


def started(cfg: ObserverConfig, x0: FloatArray | None = None) -> EkfArrays:
    a = cfg.arrays()
    obs_init(a, 0, np.zeros(9) if x0 is None else x0, cfg.initial_covariance())
    return a


def snapshot(a: EkfArrays) -> list[FloatArray]:
    return [np.array(arr, copy=True) for arr in a]


def assert_untouched(a: EkfArrays, before: list[FloatArray], counter: int) -> None:
    for name, old, new in zip(a._fields, before, a, strict=True):
        if name == "counters":
            expected = old.copy()
            expected[counter] += 1
            np.testing.assert_array_equal(new, expected)
        elif name == "meta":  # the ring itself; the gated-in-a-row count may move
            np.testing.assert_array_equal(new[: M_GATED_RUN], old[: M_GATED_RUN])
        elif name == "innovation":  # a report on the sample itself, not filter state
            continue
        else:
            np.testing.assert_array_equal(new, old, err_msg=name)


# ---------------------------------------------------------------------------
# kernels against their twins
# ---------------------------------------------------------------------------


def test_predict_matches_numpy_twin() -> None:
    rng = np.random.default_rng(1)
    prm = params()
    for _ in range(20):
        x, P = random_state(rng)
        ax, ay = rng.normal(size=2)
        want_x, want_P = twin_predict(x, P, 0.013, float(ax), float(ay), prm)
        ekf_predict(x, P, 0.013, float(ax), float(ay), prm)
        np.testing.assert_allclose(x, want_x, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(P, want_P, rtol=1e-12, atol=1e-16)
        np.testing.assert_array_equal(P, P.T)


def test_pose_update_matches_numpy_twin_across_the_heading_cut() -> None:
    rng = np.random.default_rng(2)
    H = np.zeros((3, 9))
    H[0, 0] = H[1, 1] = H[2, 2] = 1.0
    r_diag = np.array([1e-4, 2e-4, 3e-4])
    for i in range(20):
        x, P = random_state(rng)
        if i % 2:
            x[2] = math.pi - 0.01  # measurement just across +-pi
        z = x[:3] + rng.normal(size=3) * 0.01
        z[2] = math.remainder(z[2], 2 * math.pi)
        y = z - x[:3]
        y[2] = math.remainder(y[2], 2 * math.pi)
        want_x, want_P, _ = twin_update(x, P, H, y, np.diag(r_diag))
        want_x[2] = math.remainder(want_x[2], 2 * math.pi)
        assert ekf_update_pose(x, P, z, r_diag, math.inf)
        np.testing.assert_allclose(x, want_x, rtol=1e-10, atol=1e-13)
        np.testing.assert_allclose(P, want_P, rtol=1e-8, atol=1e-14)


def test_yaw_rate_update_matches_numpy_twin() -> None:
    rng = np.random.default_rng(3)
    H = np.zeros((1, 9))
    H[0, 5] = H[0, 8] = 1.0
    for _ in range(20):
        x, P = random_state(rng)
        z = x[5] + x[8] + float(rng.normal()) * 0.01
        want_x, want_P, _ = twin_update(x, P, H, np.array([z - x[5] - x[8]]), np.array([[1e-4]]))
        assert ekf_update_yaw_rate(x, P, z, 1e-4, math.inf)
        np.testing.assert_allclose(x, want_x, rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(P, want_P, rtol=1e-8, atol=1e-14)


def test_gate_uses_the_mahalanobis_distance_and_refuses_in_place() -> None:
    rng = np.random.default_rng(4)
    x, P = random_state(rng)
    H = np.zeros((3, 9))
    H[0, 0] = H[1, 1] = H[2, 2] = 1.0
    r_diag = np.array([1e-4, 1e-4, 1e-4])
    z = x[:3] + np.array([0.3, -0.2, 0.1])
    _, _, d2 = twin_update(x, P, H, z - x[:3], np.diag(r_diag))
    x0, P0 = x.copy(), P.copy()
    assert not ekf_update_pose(x, P, z, r_diag, d2 * 0.999)
    np.testing.assert_array_equal(x, x0)
    np.testing.assert_array_equal(P, P0)
    assert ekf_update_pose(x, P, z, r_diag, d2 * 1.001)
    x1, P1 = x0.copy(), P0.copy()
    assert not ekf_update_yaw_rate(x1, P1, math.nan, 1e-4, math.inf)
    np.testing.assert_array_equal(x1, x0)
    # The innovation the consistency watch judges is the gate's d^2, from the prior.
    out = np.empty(3)
    pose_innovation(x0, P0, z[0], z[1], z[2], r_diag[0], r_diag[1], r_diag[2], out)
    assert out[0] == pytest.approx(d2, rel=1e-12)
    assert out[1] == pytest.approx(math.hypot(0.3, 0.2), rel=1e-12)
    assert out[2] == pytest.approx(0.1, rel=1e-12)
    pose_innovation(x0, P0, math.nan, z[1], z[2], r_diag[0], r_diag[1], r_diag[2], out)
    assert np.isnan(out).all()


def test_the_ekf_reports_each_pose_s_innovation_fused_or_gated() -> None:
    ekf = Ekf()
    ekf.process_pose(PoseSample(0, 1.0, 2.0, 0.5))
    assert math.isnan(ekf.last_innovation().nis)  # the first pose has no prior
    for i in range(1, 30):
        ekf.process_imu(ImuSample(i * DT_NS, 0.0, 0.0, 0.0))
        ekf.process_pose(PoseSample(i * DT_NS, 1.0, 2.0, 0.5))
        fused = ekf.last_innovation()
        assert 0.0 <= fused.nis <= ekf.config.gate_pose_chi2
    assert ekf.process_pose(PoseSample(30 * DT_NS, 1.05, 2.0, 0.5)) is ObserverStatus.GATED
    gated = ekf.last_innovation()
    assert gated.nis > ekf.config.gate_pose_chi2
    assert gated.position_m == pytest.approx(0.05, rel=1e-6)
    assert ekf.fuse_pose(31 * DT_NS, math.nan, 2.0, 0.5) is ObserverStatus.NONFINITE
    assert math.isnan(ekf.last_innovation().nis)  # refused before its gate


# ---------------------------------------------------------------------------
# closed forms
# ---------------------------------------------------------------------------


def test_static_vessel_covariance_reaches_the_kalman_steady_state() -> None:
    """At rest with exact data the EKF is the linear KF of F(0): P -> the DARE solution."""
    cfg = ObserverConfig(accel_bias_walk_mps2_per_sqrt_s=0.01, gyro_bias_walk_radps_per_sqrt_s=1e-3)
    a = started(cfg)
    for i in range(1, 3001):
        obs_imu(a, i * DT_NS, 0.0, 0.0, 0.0)
        obs_pose(a, i * DT_NS, 0.0, 0.0, 0.0)
    prm = cfg.params()
    F = np.eye(9) + DT * twin_jacobian(np.zeros(9))
    q = [0, 0, 0, prm[P_Q_UV], prm[P_Q_UV], prm[P_Q_R]]
    Q = np.diag([*q, prm[P_Q_BA], prm[P_Q_BA], prm[P_Q_BR]]) * DT
    H = np.zeros((4, 9))
    H[0, 0] = H[1, 1] = H[2, 2] = H[3, 5] = H[3, 8] = 1.0
    R = np.diag(prm[[P_R_X, P_R_Y, P_R_PSI, P_R_GYRO]])
    prior = sl.solve_discrete_are(F.T, H.T, Q, R)
    post = prior - prior @ H.T @ np.linalg.solve(H @ prior @ H.T + R, H @ prior)
    scale = np.sqrt(np.outer(np.diag(post), np.diag(post)))
    assert np.max(np.abs(a.P - post) / scale) < 1e-6
    np.testing.assert_array_equal(a.x, np.zeros(9))


def test_static_vessel_with_noisy_pose_converges() -> None:
    cfg = ObserverConfig()
    rng = np.random.default_rng(5)
    truth = np.array([1.0, -2.0, 3.1])
    x0 = np.zeros(9)
    x0[:3] = truth + np.array([0.002, -0.001, 0.002])
    x0[3:6] = [0.05, -0.05, 0.05]
    a = started(cfg, x0)
    std = np.array([cfg.pose_std_m, cfg.pose_std_m, cfg.pose_yaw_std_rad])
    for i in range(1, 1001):
        ax, ay, r = rng.normal(size=3) * [
            cfg.accel_std_mps2,
            cfg.accel_std_mps2,
            cfg.gyro_std_radps,
        ]
        obs_imu(a, i * DT_NS, float(ax), float(ay), float(r))
        z = truth + rng.normal(size=3) * std
        obs_pose(a, i * DT_NS, float(z[0]), float(z[1]), float(z[2]))
    err = a.x[:6] - np.r_[truth, 0, 0, 0]
    err[2] = math.remainder(err[2], 2 * math.pi)
    sigma = np.sqrt(np.diag(a.P)[:6])
    assert np.all(np.abs(err) < 4 * sigma)
    # Averaging 100 Hz poses makes the position much better than one pose.
    assert np.all(sigma[:2] < 0.5 * cfg.pose_std_m)


# ---------------------------------------------------------------------------
# consistency on a moving vessel (truth simulated here, from the filter's model)
# ---------------------------------------------------------------------------


def simulate(
    cfg: ObserverConfig,
    seed: int,
    n_steps: int,
    delay: int = 0,
    dropout: tuple[int, int] = (0, 0),
    flush: bool = False,
) -> tuple[FloatArray, FloatArray, FloatArray, EkfArrays]:
    """Run one seeded trajectory; return errors (N, 9), NEES (N,), P traces (N,), arrays.

    Poses are delivered `delay` steps late; `flush` delivers the ones still due at the end.
    """
    rng = np.random.default_rng(seed)
    prm = cfg.params()
    P0 = cfg.initial_covariance()
    truth = np.zeros(9)
    truth[:3] = [0.5, -0.3, 2.5]
    truth[3:6] = [0.12, -0.03, 0.08]
    truth[6:9] = rng.normal(size=3) * np.sqrt(np.diag(P0)[6:9])
    x0 = truth + rng.multivariate_normal(np.zeros(9), P0)
    a = started(cfg, x0)
    pose_std = np.sqrt(prm[[P_R_X, P_R_Y, P_R_PSI]])
    poses: list[tuple[int, FloatArray]] = []
    errs = np.zeros((n_steps, 9))
    nees = np.zeros(n_steps)
    trace = np.zeros(n_steps)
    for i in range(1, n_steps + 1):
        t = i * DT
        # Truth: body accelerations slowly varying; r and the biases random walks.
        nu_dot = np.array([0.04 * math.cos(0.7 * t), 0.03 * math.sin(0.5 * t)])
        psi, u, v, r = truth[2], truth[3], truth[4], truth[5]
        f = nu_dot + np.array([-r * v, r * u])
        c, s = math.cos(psi), math.sin(psi)
        truth[0] += DT * (c * u - s * v)
        truth[1] += DT * (s * u + c * v)
        truth[2] = math.remainder(psi + DT * r, 2 * math.pi)
        truth[3:5] += DT * nu_dot
        truth[5] += math.sqrt(prm[P_Q_R] * DT) * rng.normal()
        walk = np.sqrt(prm[[P_Q_BA, P_Q_BA, P_Q_BR]] * DT)
        truth[6:9] += walk * rng.normal(size=3)
        # IMU sample at the start of step i, held over [t, t + dt).
        meas = np.r_[f, truth[5]] + truth[6:9]
        meas += rng.normal(size=3) * np.array([cfg.accel_std_mps2] * 2 + [cfg.gyro_std_radps])
        obs_imu(a, i * DT_NS, float(meas[0]), float(meas[1]), float(meas[2]))
        z = truth[:3] + rng.normal(size=3) * pose_std
        if not dropout[0] <= i < dropout[1]:
            poses.append((i * DT_NS, z))
        while poses and poses[0][0] <= (i - delay) * DT_NS:
            t_ns, zz = poses.pop(0)
            obs_pose(a, t_ns, float(zz[0]), float(zz[1]), float(zz[2]))
        e = a.x - truth
        e[2] = math.remainder(e[2], 2 * math.pi)
        errs[i - 1] = e
        nees[i - 1] = e @ np.linalg.solve(a.P, e)
        trace[i - 1] = np.trace(a.P[:2, :2])
    for t_ns, zz in poses if flush else []:
        obs_pose(a, t_ns, float(zz[0]), float(zz[1]), float(zz[2]))
    return errs, nees, trace, a


def consistency_config() -> ObserverConfig:
    # The model the truth is drawn from: no extra velocity walk, livelier biases.
    return ObserverConfig(
        velocity_walk_mps_per_sqrt_s=0.0,
        accel_bias_walk_mps2_per_sqrt_s=0.005,
        gyro_bias_walk_radps_per_sqrt_s=5e-4,
    )


def test_nees_within_chi_square_bounds_over_seeded_runs() -> None:
    cfg = consistency_config()
    runs = 12
    n_steps = 800
    nees = np.array([simulate(cfg, seed, n_steps)[1] for seed in range(runs)])
    anees = nees.mean(axis=0)[100:]
    lo, hi = stats.chi2.ppf([0.005, 0.995], 9 * runs) / runs
    inside = np.mean((anees > lo) & (anees < hi))
    # Consistent: the run-averaged NEES stays in its 99 % band nearly all the time,
    # and its time average is close to the state dimension.
    assert inside > 0.9, (inside, lo, hi)
    assert 9 * 0.85 < anees.mean() < 9 * 1.15, anees.mean()


def test_late_poses_give_the_same_estimate_as_timely_ones() -> None:
    cfg = consistency_config()
    _, _, _, on_time = simulate(cfg, 7, 300)
    _, _, _, late = simulate(cfg, 7, 300, delay=3, flush=True)
    assert on_time.counters[C_POSE_LATE] == 0
    assert late.counters[C_POSE_FUSED] == 300
    assert late.counters[C_POSE_LATE] == 299  # the last one is at the filter time
    np.testing.assert_allclose(late.x, on_time.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(late.P, on_time.P, rtol=0, atol=1e-15)


def test_out_of_order_poses_give_the_same_estimate_as_in_order() -> None:
    cfg = ObserverConfig()
    rng = np.random.default_rng(8)
    imu = rng.normal(size=(40, 3)) * 0.01
    poses = [(i * DT_NS, rng.normal(size=3) * 0.001 + [0.001 * i, 0, 0.1]) for i in range(1, 40)]
    order = list(range(len(poses)))
    shuffled = order.copy()
    for start in range(0, len(order) - 5, 5):  # reverse blocks of 5
        shuffled[start : start + 5] = order[start : start + 5][::-1]
    results = []
    x0 = np.zeros(9)
    x0[2] = 0.1
    for sequence in (order, shuffled):
        a = started(cfg, x0)
        for i in range(1, 40):
            obs_imu(a, i * DT_NS, float(imu[i, 0]), float(imu[i, 1]), float(imu[i, 2]))
        for j in sequence:
            t_ns, z = poses[j]
            status = obs_pose(a, t_ns, float(z[0]), float(z[1]), float(z[2]))
            assert status == S_FUSED
        results.append((a.x.copy(), a.P.copy()))
    np.testing.assert_allclose(results[0][0], results[1][0], atol=1e-12)
    np.testing.assert_allclose(results[0][1], results[1][1], atol=1e-14)


def test_recovers_within_half_a_second_after_a_one_second_pose_dropout() -> None:
    cfg = consistency_config()
    start, stop = 500, 600  # steps: poses lost for 1 s
    errs, _, trace, _ = simulate(cfg, 9, 800, dropout=(start, stop))
    # Covariance grows while only the IMU is fused, then falls back.
    assert np.all(np.diff(trace[start : stop - 1]) > 0)
    assert trace[stop - 2] > 10 * trace[start - 2]
    # Dead reckoning on the IMU keeps the error small during the outage.
    assert np.max(np.abs(errs[start:stop, :2])) < 0.03
    # Within 0.5 s after the outage: back to the accuracy before it.
    before = np.abs(errs[start - 100 : start]).max(axis=0)
    after = np.abs(errs[stop + 50 : stop + 150]).max(axis=0)
    assert np.all(after[:6] < 2 * before[:6] + np.array([1e-4, 1e-4, 1e-4, 1e-3, 1e-3, 1e-3]))


# ---------------------------------------------------------------------------
# bad, late and duplicate samples
# ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("sample", "status", "counter"),
    [
        ((math.nan, 0.0, 0.0), S_NONFINITE, C_POSE_NONFINITE),
        ((0.0, math.inf, 0.0), S_NONFINITE, C_POSE_NONFINITE),
        ((0.0, 0.0, -math.inf), S_NONFINITE, C_POSE_NONFINITE),
        ((1e6, 0.0, 0.0), S_ABSURD, C_POSE_ABSURD),
        ((0.5, 0.0, 0.0), S_GATED, C_POSE_GATED),  # a 0.5 m jump: an outlier
    ],
)
def test_bad_pose_is_refused_without_touching_the_state(
    sample: tuple[float, float, float], status: int, counter: int
) -> None:
    a = started(ObserverConfig())
    obs_imu(a, DT_NS, 0.01, 0.0, 0.0)
    obs_pose(a, DT_NS, 0.0, 0.0, 0.0)
    before = snapshot(a)
    assert obs_pose(a, DT_NS // 2, *sample) == status  # late, too: no history change
    assert_untouched(a, before, counter)
    again = snapshot(a)
    assert obs_pose(a, 2 * DT_NS, *sample) == status  # in the future: no advance either
    assert_untouched(a, again, counter)
    again = snapshot(a)
    assert obs_pose(a, 0, *sample) == status  # late, at a stamp the history has
    assert_untouched(a, again, counter)


@pytest.mark.parametrize(
    ("sample", "status", "counter"),
    [
        ((math.nan, 0.0, 0.0), S_NONFINITE, C_IMU_NONFINITE),
        ((0.0, 0.0, math.inf), S_NONFINITE, C_IMU_NONFINITE),
        ((100.0, 0.0, 0.0), S_ABSURD, C_IMU_ABSURD),
        ((0.0, 0.0, 50.0), S_ABSURD, C_IMU_ABSURD),
    ],
)
def test_bad_imu_is_refused_without_touching_the_state(
    sample: tuple[float, float, float], status: int, counter: int
) -> None:
    a = started(ObserverConfig())
    obs_imu(a, DT_NS, 0.01, 0.0, 0.0)
    before = snapshot(a)
    assert obs_imu(a, 2 * DT_NS, *sample) == status
    assert_untouched(a, before, counter)


def test_gated_yaw_rate_still_advances_time_with_the_acceleration() -> None:
    a = started(ObserverConfig())
    obs_imu(a, DT_NS, 0.0, 0.0, 0.0)
    assert obs_imu(a, 2 * DT_NS, 0.1, 0.0, 5.0) == S_GATED
    assert obs_time_ns(a) == 2 * DT_NS
    assert a.counters[C_GYRO_GATED] == 1
    assert a.counters[C_IMU_FUSED] == 2


def test_too_old_and_duplicate_samples_are_refused_and_counted() -> None:
    cfg = ObserverConfig(max_delay_s=0.05, history_len=8)
    a = started(cfg)
    for i in range(1, 21):
        obs_imu(a, i * DT_NS, 0.0, 0.0, 0.0)
    before = snapshot(a)
    assert obs_pose(a, 14 * DT_NS, 0.0, 0.0, 0.0) == S_TOO_OLD  # older than max_delay
    assert_untouched(a, before, C_POSE_TOO_OLD)
    assert obs_imu(a, 20 * DT_NS, 0.0, 0.0, 0.0) == S_DUPLICATE
    assert obs_pose(a, 17 * DT_NS, 0.0, 0.0, 0.0) == S_FUSED
    assert obs_pose(a, 17 * DT_NS, 0.0, 0.0, 0.0) == S_DUPLICATE
    # A full ring: a stamp between the two oldest slots has no room left.
    b = started(replace(cfg, max_delay_s=10.0, history_len=4))
    for i in range(1, 10):
        obs_imu(b, i * DT_NS, 0.0, 0.0, 0.0)
    assert obs_pose(b, 6 * DT_NS + 1, 0.0, 0.0, 0.0) == S_TOO_OLD
    assert obs_pose(b, 5 * DT_NS, 0.0, 0.0, 0.0) == S_TOO_OLD
    assert obs_pose(b, 7 * DT_NS + 1, 0.0, 0.0, 0.0) == S_FUSED
    assert b.counters[C_POSE_TOO_OLD] == 2


def test_late_imu_replaces_the_held_acceleration_from_its_stamp() -> None:
    cfg = ObserverConfig()
    timely = started(cfg)
    late = started(cfg)
    for i in range(1, 6):
        obs_imu(timely, i * DT_NS, 0.2, -0.1, 0.01)
        obs_pose(timely, i * DT_NS + DT_NS // 2, 0.0, 0.0, 0.0)
    for i in (1, 2, 4, 5):
        obs_imu(late, i * DT_NS, 0.2, -0.1, 0.01)
        obs_pose(late, i * DT_NS + DT_NS // 2, 0.0, 0.0, 0.0)
    obs_pose(late, 3 * DT_NS + DT_NS // 2, 0.0, 0.0, 0.0)
    assert obs_imu(late, 3 * DT_NS, 0.2, -0.1, 0.01) == S_FUSED
    np.testing.assert_allclose(late.x, timely.x, atol=1e-13)
    np.testing.assert_allclose(late.P, timely.P, atol=1e-15)
    assert late.counters[C_IMU_LATE] == 1


# ---------------------------------------------------------------------------
# the Python face
# ---------------------------------------------------------------------------


def test_ekf_starts_at_the_first_pose_and_reports_the_estimate() -> None:
    ekf = Ekf()
    assert not ekf.initialized
    assert ekf.time_ns is None
    with pytest.raises(ObserverNotInitializedError, match="no pose"):
        ekf.estimate()
    assert ekf.process_imu(ImuSample(0, 0.0, 0.0, 0.0)) is ObserverStatus.NOT_INITIALIZED
    assert ekf.fuse_pose(5, math.nan, 0.0, 0.0) is ObserverStatus.NONFINITE
    assert ekf.process_pose(PoseSample(10, 1.0, 2.0, 3.5)) is ObserverStatus.FUSED
    assert ekf.time_ns == 10
    for i in range(1, 50):
        ekf.process_imu(ImuSample(10 + i * DT_NS, 0.0, 0.0, 0.0))
        ekf.process_pose(PoseSample(10 + i * DT_NS, 1.0, 2.0, 3.5))
    est = ekf.estimate()
    assert est.t_ns == 10 + 49 * DT_NS
    np.testing.assert_allclose(est.eta, [1.0, 2.0, 3.5 - 2 * math.pi], atol=1e-9)
    np.testing.assert_allclose(est.nu, 0.0, atol=1e-9)
    assert est.covariance.shape == (6, 6)
    assert est.full_covariance.shape == (9, 9)
    counts = ekf.counters()
    assert (counts.pose_fused, counts.imu_fused, counts.not_initialized) == (50, 49, 1)
    assert counts.pose_nonfinite == 1
    assert counts.rejected == 2


def test_ekf_class_runs_the_same_kernels() -> None:
    cfg = ObserverConfig()
    ekf = Ekf(cfg)
    ekf.initialize(0, np.array([0.1, 0.2, 0.3]), np.array([0.1, 0.0, 0.05]))
    x0 = np.zeros(9)
    x0[:6] = [0.1, 0.2, 0.3, 0.1, 0.0, 0.05]
    a = started(cfg, x0)
    for i in range(1, 30):
        sample = ImuSample(i * DT_NS, 0.01 * i, -0.02, 0.05)
        ekf.process_imu(sample)
        obs_imu(a, i * DT_NS, 0.01 * i, -0.02, 0.05)
        ekf.process_pose(PoseSample(i * DT_NS, 0.1 + 0.001 * i, 0.2, 0.3))
        obs_pose(a, i * DT_NS, 0.1 + 0.001 * i, 0.2, 0.3)
    np.testing.assert_array_equal(ekf.estimate().full_covariance, a.P)
    np.testing.assert_array_equal(ekf.arrays.x, a.x)


def test_ekf_refuses_wrong_frames_and_shapes() -> None:
    ekf = Ekf()
    with pytest.raises(ObserverInputError, match="arena"):
        ekf.process_pose(PoseSample(0, 1.0, 2.0, 0.0, Frame.LAB_NED))
    with pytest.raises(ObserverInputError, match="eta"):
        ekf.initialize(0, np.array([0.0, math.nan, 0.0]))
    with pytest.raises(ObserverInputError, match="covariance"):
        ekf.initialize(0, np.zeros(3), covariance=np.eye(6))


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("pose_std_m", -0.001, "pose_std_m"),
        ("gyro_std_radps", 0.0, "gyro_std_radps"),
        ("accel_std_mps2", math.nan, "accel_std_mps2"),
        ("velocity_walk_mps_per_sqrt_s", -1.0, "velocity_walk"),
        ("gate_pose_chi2", 0.0, "gate_pose_chi2"),
        ("history_len", 1, "history_len"),
        ("history_len", 2.5, "history_len"),
    ],
)
def test_invalid_config_is_refused(field: str, value: float, match: str) -> None:
    with pytest.raises(ObserverConfigError, match=match):
        ObserverConfig(**{field: value})  # type: ignore[arg-type]


def test_bias_freeze_reduces_to_the_six_state_filter() -> None:
    cfg = ObserverConfig(estimate_bias=False)
    a = started(cfg)
    for i in range(1, 100):
        obs_imu(a, i * DT_NS, 0.05, 0.0, 0.01)
        obs_pose(a, i * DT_NS, 0.0, 0.0, 0.0)
    np.testing.assert_array_equal(a.x[6:], 0.0)
    np.testing.assert_array_equal(a.P[6:, :], 0.0)


@pytest.mark.parametrize("limit", [0, 20])
def test_persistent_disagreement_restarts_the_pose_only_if_enabled(limit: int) -> None:
    cfg = ObserverConfig(reset_after_gated_poses=limit)
    a = started(cfg)
    statuses = []
    for i in range(1, 41):
        obs_imu(a, i * DT_NS, 0.0, 0.0, 0.0)
        # The vessel was really 0.5 m away (a wrong start): every pose is gated at first.
        statuses.append(obs_pose(a, (i - 1) * DT_NS, 0.5, 0.0, 0.1))
    if limit == 0:
        assert statuses == [S_GATED] * 40
        assert a.counters[C_POSE_RESET] == 0
        return
    assert statuses[:19] == [S_GATED] * 19
    assert statuses[19] == S_RESET
    assert statuses[20:] == [S_FUSED] * 20
    assert a.counters[C_POSE_RESET] == 1
    assert a.counters[C_POSE_GATED] == 19
    np.testing.assert_allclose(a.x[:3], [0.5, 0.0, 0.1], atol=1e-3)


def test_imu_biases_are_learned_and_do_not_bias_the_velocity() -> None:
    cfg = ObserverConfig()
    rng = np.random.default_rng(12)
    bias = np.array([0.06, -0.04, 0.004])
    a = started(cfg)
    for i in range(1, 2001):  # 20 s at rest
        noise = rng.normal(size=3) * [cfg.accel_std_mps2, cfg.accel_std_mps2, cfg.gyro_std_radps]
        f = bias + noise
        obs_imu(a, i * DT_NS, float(f[0]), float(f[1]), float(f[2]))
        z = rng.normal(size=3) * [cfg.pose_std_m, cfg.pose_std_m, cfg.pose_yaw_std_rad]
        obs_pose(a, i * DT_NS, float(z[0]), float(z[1]), float(z[2]))
    sigma = np.sqrt(np.diag(a.P))
    assert np.all(np.abs(a.x[6:9] - bias) < 4 * sigma[6:9])
    assert np.all(sigma[6:9] < 0.1 * np.abs(bias))
    assert np.all(np.abs(a.x[3:6]) < 4 * sigma[3:6])
    assert np.all(np.abs(a.x[3:5]) < 0.003)


def test_accelerometer_bias_jump_does_not_make_the_filter_run_away() -> None:
    """A 0.3 m/s^2 jump (about 2 deg of tilt) gates poses; the restart brings it back."""
    cfg = ObserverConfig()
    rng = np.random.default_rng(13)
    a = started(cfg)
    err = np.zeros((600, 6))
    for i in range(1, 601):  # at rest; the bias jumps at 1 s
        bias = np.array([0.3, -0.3, 0.0]) if i > 100 else np.zeros(3)
        f = bias + rng.normal(size=3) * [cfg.accel_std_mps2, cfg.accel_std_mps2, cfg.gyro_std_radps]
        obs_imu(a, i * DT_NS, float(f[0]), float(f[1]), float(f[2]))
        z = rng.normal(size=3) * [cfg.pose_std_m, cfg.pose_std_m, cfg.pose_yaw_std_rad]
        obs_pose(a, (i - 1) * DT_NS, float(z[0]), float(z[1]), float(z[2]))
        err[i - 1] = a.x[:6]
    assert a.counters[C_POSE_RESET] <= 2
    assert np.max(np.abs(err[:, :2])) < 0.02
    # Two seconds after the jump the velocity is back to millimetres per second.
    assert np.max(np.abs(err[300:, 3:5])) < 0.01
    np.testing.assert_allclose(a.x[6:8], [0.3, -0.3], atol=0.02)


def test_prediction_to_a_later_time_changes_nothing() -> None:
    ekf = Ekf()
    ekf.initialize(0, np.array([0.0, 0.0, 0.3]), np.array([0.1, 0.02, 0.05]))
    ekf.process_imu(ImuSample(DT_NS, 0.2, -0.1, 0.05))
    before = snapshot(ekf.arrays)
    later = ekf.predicted(DT_NS + 25_000_000)
    for old, new in zip(before, ekf.arrays, strict=True):
        np.testing.assert_array_equal(new, old)
    x, P = before[0].copy(), before[1].copy()
    ekf_predict(x, P, 0.025, 0.2, -0.1, ekf.config.params())
    np.testing.assert_array_equal(later.eta, x[:3])
    np.testing.assert_array_equal(later.full_covariance, P)
    assert later.t_ns == DT_NS + 25_000_000
    np.testing.assert_array_equal(ekf.predicted(DT_NS).nu, ekf.estimate().nu)
    with pytest.raises(ObserverInputError, match="predict back"):
        ekf.predicted(0)
    with pytest.raises(ObserverNotInitializedError):
        Ekf().predicted(0)


def test_a_stale_accelerometer_sample_drives_the_prediction_for_the_hold_only() -> None:
    from hil.controllers.observer_math import I_U, N_STATE, ekf_predict

    config = ObserverConfig(accel_hold_s=0.1)
    params = config.params()
    x = np.zeros(N_STATE)
    P = np.eye(N_STATE) * 1e-4
    # The IMU's last sample says 0.5 m/s^2 forward, then nothing for a whole second.
    ekf_predict(x, P, 1.0, 0.5, 0.0, params)
    assert x[I_U] == pytest.approx(0.05)  # 0.1 s of 0.5 m/s^2, then constant velocity
    # Within the hold, the sample drives the whole step.
    x2 = np.zeros(N_STATE)
    ekf_predict(x2, np.eye(N_STATE) * 1e-4, 0.01, 0.5, 0.0, params)
    assert x2[I_U] == pytest.approx(0.005)
    with pytest.raises(ObserverConfigError, match="accel_hold_s"):
        ObserverConfig(accel_hold_s=0.0)
