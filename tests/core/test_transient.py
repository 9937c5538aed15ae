"""The transient budget: validation, closed forms, a brute-force integral, and the bound itself."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.core.transient import BudgetClass, TransientBudget, TransientBudgetError

FloatArray = np.ndarray


def budget(env: FloatArray, bin_s: float = 0.25) -> TransientBudget:
    return TransientBudget(bin_s, env, 0.002, 0.001, "test")


def random_budget(seed: int, n_bins: int = 8) -> TransientBudget:
    rng = np.random.default_rng(seed)
    env = rng.uniform(0.0, 0.1, size=(2, n_bins, 3))
    env[:, :, 2] *= 3.0  # rad/s
    return budget(env)


def test_zero_is_all_zero_over_the_period() -> None:
    z = TransientBudget.zero(2.0)
    assert z.n_bins == 8
    assert z.bin_s == pytest.approx(0.25)
    assert z.horizon_s() == pytest.approx(2.0)
    assert z.is_zero()
    t = np.linspace(0.0, 3.0, 7)
    np.testing.assert_array_equal(z.heading_bound_rad(0, t), 0.0)
    np.testing.assert_array_equal(z.position_bound_m(1, np.array([0.0, 0.2]), t), 0.0)


def test_constant_envelope_has_the_closed_form() -> None:
    # env constant (eu, ev, er): theta = er t, rho = hypot(eu, ev) t + speed er t^2 / 2.
    eu, ev, er = 0.01, 0.02, 0.05
    env = np.broadcast_to(np.array([eu, ev, er]), (2, 8, 3)).copy()
    b = budget(env)
    t = np.array([0.0, 0.1, 0.25, 0.6, 2.0, 3.5])  # 3.5 s: past the horizon, last bin extended
    speed = np.array([0.0, 0.1, 0.25])
    np.testing.assert_allclose(b.heading_bound_rad(BudgetClass.HOLD, t), er * t, atol=1e-15)
    expected = math.hypot(eu, ev) * t[None, :] + speed[:, None] * er * t[None, :] ** 2 / 2
    np.testing.assert_allclose(
        b.position_bound_m(BudgetClass.CHANGE, speed, t), expected, rtol=1e-12, atol=1e-15
    )


def brute_force(
    env: FloatArray, bin_s: float, speed: float, t_end: float, n: int
) -> tuple[float, float]:
    """Return (theta, rho) at t_end by midpoint sums over n steps of the definition."""
    dt = t_end / n
    s = (np.arange(n) + 0.5) * dt
    j = np.minimum(np.floor(s / bin_s).astype(int), env.shape[0] - 1)
    theta_rate = env[j, 2]
    theta = np.concatenate(([0.0], np.cumsum(theta_rate * dt)))  # at the step edges
    theta_mid = 0.5 * (theta[:-1] + theta[1:])  # theta is linear over a step inside a bin
    rho = np.sum(np.hypot(env[j, 0], env[j, 1]) * dt) + speed * np.sum(theta_mid * dt)
    return float(theta[-1]), float(rho)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_bounds_match_a_brute_force_integral(seed: int) -> None:
    b = random_budget(seed)
    rng = np.random.default_rng(100 + seed)
    times = np.concatenate(([0.0, 0.25, 1.0, 2.0, 2.7], rng.uniform(0.0, 2.5, 6)))
    speeds = np.array([0.0, 0.07, 0.2236])
    for cls in (0, 1):
        theta = b.heading_bound_rad(cls, times)
        rho = b.position_bound_m(cls, speeds, times)
        assert rho.shape == (3, times.size)
        for k, t_end in enumerate(times):
            for i, speed in enumerate(speeds):
                if t_end == 0.0:
                    assert theta[k] == 0.0
                    assert rho[i, k] == 0.0
                    continue
                th, r = brute_force(b.envelopes[cls], b.bin_s, float(speed), float(t_end), 200_000)
                # A step straddling a bin edge errs by O(dt): 1e-5 relative, far below a
                # formula error.
                assert theta[k] == pytest.approx(th, rel=1e-5, abs=1e-12)
                assert rho[i, k] == pytest.approx(r, rel=1e-5, abs=1e-12)


def test_bounds_grow_with_time_and_speed() -> None:
    b = random_budget(5)
    t = np.linspace(0.0, 2.5, 101)
    theta = b.heading_bound_rad(1, t)
    rho = b.position_bound_m(1, np.array([0.0, 0.1, 0.2]), t)
    assert np.all(np.diff(theta) >= 0.0)
    assert np.all(np.diff(rho, axis=1) >= 0.0)
    assert np.all(np.diff(rho, axis=0) >= 0.0)


def rotation(psi: FloatArray) -> FloatArray:
    c, s = np.cos(psi), np.sin(psi)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


@pytest.mark.parametrize("switching", [True, False])
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_any_velocity_inside_the_envelope_stays_inside_the_bound(
    seed: int, switching: bool
) -> None:
    # The claim of the module docstring, flown: velocity errors at the envelope's corners
    # (switching every 50 ms, or all +), integrated finely, against the exact arc.
    b = random_budget(seed)
    rng = np.random.default_rng(seed)
    dt = 1e-4
    t = np.arange(0.0, 2.0 + dt / 2, dt)
    for cls in (0, 1):
        u = np.array([rng.uniform(-0.1, 0.2), rng.uniform(-0.1, 0.1), rng.uniform(-0.2, 0.2)])
        j = np.minimum(np.floor(t / b.bin_s).astype(int), b.n_bins - 1)
        signs = np.where(rng.random((t.size, 3)) < 0.5, -1.0, 1.0)
        if switching:
            signs = np.repeat(signs[::500], 500, axis=0)[: t.size]
        else:
            signs[:] = np.sign(u) + (u == 0.0)  # errors along the reference: the worst case
        nu = u[None, :] + signs * b.envelopes[cls, j]
        psi0 = rng.uniform(-math.pi, math.pi)
        psi = psi0 + np.concatenate(([0.0], np.cumsum(nu[:-1, 2] * dt)))
        p = np.concatenate(
            (
                [[0.0, 0.0]],
                np.cumsum(np.einsum("kij,kj->ki", rotation(psi), nu[:, :2])[:-1] * dt, axis=0),
            )
        )
        psibar = psi0 + u[2] * t
        pbar = np.concatenate(
            ([[0.0, 0.0]], np.cumsum((rotation(psibar) @ u[:2])[:-1] * dt, axis=0))
        )
        dev_p = np.hypot(*(p - pbar).T)
        dev_psi = np.abs(psi - psibar)
        speed = np.array([math.hypot(u[0], u[1])])
        # The Euler sums differ from the integrals by O(dt); allow that much.
        assert np.all(dev_psi <= b.heading_bound_rad(cls, t) + 1e-9)
        assert np.all(dev_p <= b.position_bound_m(cls, speed, t)[0] + 1e-6)
        if not switching:  # the heading bound is reached, the position bound nearly
            assert dev_psi[-1] == pytest.approx(b.heading_bound_rad(cls, t[-1:])[0], rel=1e-3)
            assert dev_p[-1] > 0.5 * b.position_bound_m(cls, speed, t[-1:])[0, 0]


def test_envelopes_are_copied_and_read_only() -> None:
    env = np.zeros((2, 8, 3))
    b = budget(env)
    env[0, 0, 0] = 1.0
    assert b.envelopes[0, 0, 0] == 0.0
    with pytest.raises(ValueError, match="read-only"):
        b.envelopes[0, 0, 0] = 1.0


def test_equality_and_digest_follow_the_numbers() -> None:
    a = random_budget(1)
    same = TransientBudget(a.bin_s, a.envelopes.copy(), 0.002, 0.001, "test")
    assert a == same
    assert hash(a) == hash(same)
    assert a.digest() == same.digest()
    assert len(a.digest()) == 16
    env = a.envelopes.copy()
    env[1, 7, 2] += 1e-4
    other = TransientBudget(a.bin_s, env, 0.002, 0.001, "test")
    assert a != other
    assert a.digest() != other.digest()
    assert a.digest() != TransientBudget(a.bin_s, a.envelopes, 0.003, 0.001).digest()
    assert a.digest() == TransientBudget(a.bin_s, a.envelopes, 0.002, 0.001, "x").digest()
    assert a.digest() in repr(a)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"bin_s": 0.0}, "bin_s must be > 0"),
        ({"bin_s": math.nan}, "bin_s must be finite"),
        ({"bin_s": "0.25"}, "bin_s must be a number"),
        ({"envelopes": np.zeros((2, 8))}, "shape"),
        ({"envelopes": np.zeros((3, 8, 3))}, "shape"),
        ({"envelopes": np.zeros((2, 0, 3))}, "shape"),
        ({"envelopes": np.full((2, 8, 3), math.inf)}, "finite"),
        ({"envelopes": -np.ones((2, 8, 3))}, r">= 0.*class 0, bin 0, axis 0"),
        ({"estimation_position_m": -1e-3}, "estimation_position_m must be >= 0"),
        ({"estimation_heading_rad": math.nan}, "estimation_heading_rad must be finite"),
    ],
)
def test_a_bad_budget_is_refused(kwargs: dict[str, object], match: str) -> None:
    args: dict[str, object] = {
        "bin_s": 0.25,
        "envelopes": np.zeros((2, 8, 3)),
        "estimation_position_m": 0.0,
        "estimation_heading_rad": 0.0,
    }
    args.update(kwargs)
    with pytest.raises(TransientBudgetError, match=match):
        TransientBudget(**args)  # type: ignore[arg-type]


def test_bad_questions_are_refused() -> None:
    b = random_budget(0)
    with pytest.raises(TransientBudgetError, match="class must be 0"):
        b.heading_bound_rad(2, np.array([0.0]))
    with pytest.raises(TransientBudgetError, match="t_s must be finite and >= 0"):
        b.heading_bound_rad(0, np.array([-0.1]))
    with pytest.raises(TransientBudgetError, match=r"t_s must have shape \(T,\)"):
        b.heading_bound_rad(0, np.zeros((2, 2)))
    with pytest.raises(TransientBudgetError, match="speed_mps must be finite and >= 0"):
        b.position_bound_m(0, np.array([-0.1]), np.array([1.0]))
    with pytest.raises(TransientBudgetError, match=r"speed_mps must have shape \(m,\)"):
        b.position_bound_m(0, 0.1, np.array([1.0]))
    with pytest.raises(TransientBudgetError, match="tau_s > 0"):
        TransientBudget.zero(0.0)
    assert issubclass(TransientBudgetError, ValueError)
