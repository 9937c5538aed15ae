"""NumPy twins of the vessel kernels, written from VESSEL.md independently of them."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hil.model.coefficients import ENTERPRISE_I

F = NDArray[np.float64]
P = ENTERPRISE_I
M_INV, COEF = P.kernel_arrays()
M = P.mass_matrix()

# Operating range of the paper (input set U1), widened a little.
U_RANGE = (-0.15, 0.25)
V_RANGE = (-0.15, 0.15)
R_RANGE = (-0.3, 0.3)


def c_twin(nu: F) -> F:
    u, v, r = nu
    m, xg = P.m_kg, P.xg_m
    c13 = (-m * xg + P.y_rdot) * r + (-m + P.y_vdot) * v
    c23 = (m - P.x_udot) * u
    return np.array([[0.0, 0.0, c13], [0.0, 0.0, c23], [-c13, -c23, 0.0]])


def d_twin(nu: F) -> F:
    u, v, r = nu
    p = P
    d11 = -p.xu - p.xuu * abs(u) - p.xuuu * u**2
    d22 = -p.yv - p.yvv * abs(v) - p.yvvv * v**2 - p.yrv * abs(r)
    d23 = -p.yr - p.yrr * abs(r) - p.yrrr * r**2 - p.yvr * abs(v)
    d32 = -p.nv - p.nvv * abs(v) - p.nvvv * v**2 - p.nrv * abs(r)
    d33 = -p.nr - p.nrr * abs(r) - p.nrrr * r**2 - p.nvr * abs(v)
    return np.array([[d11, 0.0, 0.0], [0.0, d22, d23], [0.0, d32, d33]])


def accel_twin(nu: F, force: F) -> F:
    out = np.linalg.solve(M, force - (c_twin(nu) + d_twin(nu)) @ nu)
    return np.asarray(out, dtype=np.float64)


def rot(psi: float) -> F:
    c, s = math.cos(psi), math.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def random_nu(rng: np.random.Generator) -> F:
    return np.array([rng.uniform(*U_RANGE), rng.uniform(*V_RANGE), rng.uniform(*R_RANGE)])
