"""Environmental load b(t) on the vessel: constant + first-order Gauss-Markov + sinusoid.

The load enters the model as ``M nu_dot + C(nu) nu + D(nu) nu = tau + b``
(:mod:`hil.model.dynamics`); series are time-major (N, 3) over (X N, Y N, N N m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hil.core.arrays import FloatArray
from hil.core.jit import njit
from hil.model.errors import EnvironmentConfigError


@dataclass(frozen=True, slots=True)
class EnvironmentalLoad:
    """Slowly varying environmental load b(t) = constant + Gauss-Markov + sinusoid.

    Zero by default. The Gauss-Markov part is a first-order process per axis,
    b_gm[k+1] = a b_gm[k] + sqrt(1 - a^2) sigma w[k], a = exp(-dt / T), w ~ N(0, 1),
    stationary with standard deviation sigma and started from its stationary law;
    seeded, so a series is reproducible.

    Attributes:
        constant_n: Constant part (X, Y, N), (N, N, N m).
        gm_std_n: Stationary standard deviation of the Gauss-Markov part per axis.
        gm_time_constant_s: Correlation time T of the Gauss-Markov part (s).
        sine_amplitude_n: Amplitude of the sinusoidal part per axis.
        sine_period_s: Period of the sinusoidal part (s).
        seed: Seed of the Gauss-Markov noise.
    """

    constant_n: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gm_std_n: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gm_time_constant_s: float = 30.0
    sine_amplitude_n: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sine_period_s: float = 20.0
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("constant_n", "gm_std_n", "sine_amplitude_n"):
            value = getattr(self, name)
            if len(value) != 3 or not all(math.isfinite(v) for v in value):
                raise EnvironmentConfigError(f"{name} must be 3 finite numbers, got {value!r}")
        if any(s < 0.0 for s in self.gm_std_n):
            raise EnvironmentConfigError(f"gm_std_n must be non-negative, got {self.gm_std_n!r}")
        for name in ("gm_time_constant_s", "sine_period_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise EnvironmentConfigError(f"{name} must be positive, got {value!r}")

    def series(self, n_steps: int, dt_s: float) -> FloatArray:
        """Return b at t = k dt_s for k = 0 .. n_steps - 1, shape (n_steps, 3), time-major."""
        if n_steps < 0 or not (math.isfinite(dt_s) and dt_s > 0.0):
            raise EnvironmentConfigError(
                f"need n_steps >= 0 and dt_s > 0, got {n_steps!r}, {dt_s!r}"
            )
        out = np.tile(np.asarray(self.constant_n, dtype=np.float64), (n_steps, 1))
        t = np.arange(n_steps) * dt_s
        amp = np.asarray(self.sine_amplitude_n)
        if np.any(amp != 0.0):
            out += amp[None, :] * np.sin(2.0 * math.pi * t / self.sine_period_s)[:, None]
        std = np.asarray(self.gm_std_n)
        if np.any(std != 0.0) and n_steps > 0:
            rng = np.random.default_rng(self.seed)
            w = rng.standard_normal((n_steps, 3))
            out += gauss_markov_kernel(w, std, math.exp(-dt_s / self.gm_time_constant_s))
        return out


@njit
def gauss_markov_kernel(w: FloatArray, std: FloatArray, a: float) -> FloatArray:
    """Return the first-order Gauss-Markov series driven by unit noise ``w`` (N, 3)."""
    n = w.shape[0]
    out = np.empty((n, 3))
    g = math.sqrt(1.0 - a * a)
    for i in range(3):
        out[0, i] = std[i] * w[0, i]
    for k in range(1, n):
        for i in range(3):
            out[k, i] = a * out[k - 1, i] + g * std[i] * w[k, i]
    return out
