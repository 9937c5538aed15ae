"""C/S Enterprise I's coefficients, and the array layout the dynamics kernels read.

:class:`VesselParams` holds the rigid-body, added-mass and damping coefficients
(Fossen notation, SI units; ``shared/VESSEL.md``); :meth:`VesselParams.kernel_arrays`
packs them as ``m_inv`` (3, 3), the inverse inertia matrix, and ``coef`` (N_COEF,),
indexed by the ``I_*`` constants below, for :mod:`hil.model.dynamics`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hil.core.arrays import FloatArray
from hil.model.errors import VesselConfigError

__all__ = ["ENTERPRISE_I", "N_COEF", "VesselParams"]

# Layout of the `coef` array the kernels read.
I_M = 0
I_XG = 1
I_XUD = 2
I_YVD = 3
I_YRD = 4
I_XU = 5
I_XUU = 6
I_XUUU = 7
I_YV = 8
I_YVV = 9
I_YVVV = 10
I_YR = 11
I_YRR = 12
I_YRRR = 13
I_YRV = 14
I_YVR = 15
I_NV = 16
I_NVV = 17
I_NVVV = 18
I_NR = 19
I_NRR = 20
I_NRRR = 21
I_NRV = 22
I_NVR = 23
I_DAMPING_ON = 24
N_COEF = 25


@dataclass(frozen=True, slots=True)
class VesselParams:
    """Rigid-body, added-mass and damping coefficients (Fossen notation, SI units).

    Defaults are C/S Enterprise I (Skåtun 2011, as used by the lab's simulator
    ``cybership_enterprise1.py``). Damping uses the usual form for this set:

        d11 = -Xu - Xuu|u| - Xuuu u^2
        d22 = -Yv - Yvv|v| - Yvvv v^2 - Yrv|r|
        d23 = -Yr - Yrr|r| - Yrrr r^2 - Yvr|v|
        d32 = -Nv - Nvv|v| - Nvvv v^2 - Nrv|r|
        d33 = -Nr - Nrr|r| - Nrrr r^2 - Nvr|v|

    The lab's file differs: it computes d33 = -Nr - Nvr|v| - Nrrr r^2 (no Nrr term)
    and d32 = -Nv - Nvvv|v| - Nr v^2 - Nrv|r| (indices shifted by one into the N
    array, so Nr multiplies v^2); that looks like an indexing bug, so the textbook
    form is used here. Xvv is listed by the lab but unused in d11 by either form.

    Note:
        With these coefficients D is not dissipative in the strict sense:
        d23 = -Yr = 7.25 exceeds 2 sqrt(d22 d33), so nu^T D(nu) nu < 0 where v and r
        have opposite signs (about -0.159 at (0, -0.2, 0.4)). The model is still
        stable: M^-1 D(0) has eigenvalues with positive real parts (0.041, 0.061,
        0.628 1/s) and a free coast decays to rest.

    Attributes:
        m_kg: Rigid-body mass (kg).
        iz_kgm2: Yaw moment of inertia about the body origin (kg m^2).
        xg_m: Longitudinal position of the centre of gravity (m).
        x_udot: Added mass X_udot (kg), negative.
        y_vdot: Added mass Y_vdot (kg).
        y_rdot: Added mass Y_rdot (kg m).
        n_vdot: Added mass N_vdot (kg m).
        n_rdot: Added inertia N_rdot (kg m^2).
        xu, xuu, xuuu: Surge damping (N s/m, N s^2/m^2, N s^3/m^3).
        yv, yvv, yvvv, yr, yrr, yrrr, yrv, yvr: Sway damping coefficients.
        nv, nvv, nvvv, nr, nrr, nrrr, nrv, nvr: Yaw damping coefficients.
        damping_enabled: False switches D off (for energy-conservation checks).
    """

    m_kg: float = 14.11
    iz_kgm2: float = 1.76
    xg_m: float = 0.0375
    x_udot: float = -2.0
    y_vdot: float = -10.0
    y_rdot: float = 0.0
    n_vdot: float = 0.0
    n_rdot: float = -1.0
    xu: float = -0.6555
    xuu: float = 0.3545
    xuuu: float = -3.787
    yv: float = -1.3443
    yvv: float = -2.776
    yvvv: float = -65.91
    yr: float = -7.25
    yrr: float = -3.45
    yrrr: float = 0.0
    yrv: float = -0.805
    yvr: float = -0.845
    nv: float = 0.0
    nvv: float = -0.2088
    nvvv: float = 0.0
    nr: float = -1.9
    nrr: float = -0.75
    nrrr: float = 0.0
    nrv: float = 0.130
    nvr: float = 0.080
    damping_enabled: bool = True

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if isinstance(value, float) and not math.isfinite(value):
                raise VesselConfigError(f"vessel parameter {name} must be finite, got {value!r}")
        if self.m_kg <= 0.0:
            raise VesselConfigError(f"mass m_kg must be positive, got {self.m_kg!r}")
        if self.iz_kgm2 <= 0.0:
            raise VesselConfigError(f"inertia iz_kgm2 must be positive, got {self.iz_kgm2!r}")
        m = self.mass_matrix()
        if not np.allclose(m, m.T, rtol=0.0, atol=1e-12):
            raise VesselConfigError(
                f"inertia matrix M must be symmetric (y_rdot == n_vdot), got "
                f"y_rdot={self.y_rdot!r}, n_vdot={self.n_vdot!r}"
            )
        eig = np.linalg.eigvalsh(m)
        if eig[0] <= 0.0:
            raise VesselConfigError(
                f"inertia matrix M is not positive definite (eigenvalues {eig.tolist()!r}): "
                f"M = {m.tolist()!r}"
            )

    def mass_matrix(self) -> FloatArray:
        """Return M = M_RB + M_A, shape (3, 3), over (u, v, r)."""
        m, xg = self.m_kg, self.xg_m
        return np.array(
            [
                [m - self.x_udot, 0.0, 0.0],
                [0.0, m - self.y_vdot, m * xg - self.y_rdot],
                [0.0, m * xg - self.n_vdot, self.iz_kgm2 - self.n_rdot],
            ]
        )

    def kernel_arrays(self) -> tuple[FloatArray, FloatArray]:
        """Return ``(m_inv (3, 3), coef (N_COEF,))``, the arrays the kernels read."""
        coef = np.zeros(N_COEF)
        coef[I_M] = self.m_kg
        coef[I_XG] = self.xg_m
        coef[I_XUD] = self.x_udot
        coef[I_YVD] = self.y_vdot
        coef[I_YRD] = self.y_rdot
        values = (
            self.xu, self.xuu, self.xuuu,
            self.yv, self.yvv, self.yvvv, self.yr, self.yrr, self.yrrr, self.yrv, self.yvr,
            self.nv, self.nvv, self.nvvv, self.nr, self.nrr, self.nrrr, self.nrv, self.nvr,
        )  # fmt: skip
        coef[I_XU : I_NVR + 1] = values
        coef[I_DAMPING_ON] = 1.0 if self.damping_enabled else 0.0
        m_inv = np.asarray(np.linalg.inv(self.mass_matrix()), dtype=np.float64)
        return m_inv, coef


ENTERPRISE_I = VesselParams()
"""The paper's simulation model, C/S Enterprise I."""
