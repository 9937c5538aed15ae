"""Tests of the environmental load b(t): zero default, seeded, stationary, kernel twin."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from hil.model.environment import EnvironmentalLoad, gauss_markov_kernel
from hil.model.errors import EnvironmentConfigError


def test_environment_zero_by_default() -> None:
    assert np.all(EnvironmentalLoad().series(100, 0.01) == 0.0)


def test_environment_seeded_and_stationary() -> None:
    env = EnvironmentalLoad(
        constant_n=(0.1, -0.05, 0.0), gm_std_n=(0.2, 0.1, 0.05), gm_time_constant_s=1.0, seed=3
    )
    a = env.series(200_000, 0.01)
    np.testing.assert_array_equal(a, env.series(200_000, 0.01))
    assert not np.array_equal(a, replace(env, seed=4).series(200_000, 0.01))
    np.testing.assert_allclose(a.mean(axis=0), [0.1, -0.05, 0.0], atol=0.03)
    np.testing.assert_allclose(a.std(axis=0), [0.2, 0.1, 0.05], rtol=0.1)
    # Slowly varying: one-step changes (rms sqrt(2 dt / T) sigma) are far below the spread.
    step_rms = np.sqrt(np.mean(np.diff(a, axis=0) ** 2, axis=0))
    assert np.all(step_rms < 0.2 * a.std(axis=0))


def test_environment_sinusoid() -> None:
    env = EnvironmentalLoad(sine_amplitude_n=(0.0, 0.3, 0.0), sine_period_s=4.0)
    b = env.series(401, 0.01)
    assert b[100, 1] == pytest.approx(0.3)
    assert b[300, 1] == pytest.approx(-0.3)


def test_gauss_markov_kernel_matches_twin() -> None:
    rng = np.random.default_rng(6)
    w = rng.standard_normal((50, 3))
    std = np.array([1.0, 2.0, 0.5])
    a = 0.9
    twin = np.empty((50, 3))
    twin[0] = std * w[0]
    for k in range(1, 50):
        twin[k] = a * twin[k - 1] + math.sqrt(1 - a * a) * std * w[k]
    np.testing.assert_allclose(gauss_markov_kernel(w, std, a), twin, atol=1e-14)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"gm_std_n": (-1.0, 0.0, 0.0)}, "gm_std_n must be non-negative"),
        ({"gm_time_constant_s": 0.0}, "gm_time_constant_s must be positive"),
        ({"constant_n": (math.nan, 0.0, 0.0)}, "constant_n must be 3 finite numbers"),
    ],
)
def test_environment_config_refused(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(EnvironmentConfigError, match=match):
        EnvironmentalLoad(**kwargs)  # type: ignore[arg-type]
