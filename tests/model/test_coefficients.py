"""Enterprise I coefficients: the published mass matrix, refused settings, kernel arrays."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from hil.model.coefficients import VesselParams
from hil.model.dynamics import damping_matrix
from hil.model.errors import VesselConfigError
from tests.model.twins import M, P


def test_mass_matrix_matches_published() -> None:
    expected = np.array([[16.11, 0.0, 0.0], [0.0, 24.11, 0.5291], [0.0, 0.5291, 2.76]])
    np.testing.assert_allclose(M, expected, atol=1e-3)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"m_kg": -14.11}, "mass m_kg must be positive, got -14.11"),
        ({"iz_kgm2": 0.0}, "inertia iz_kgm2 must be positive"),
        ({"iz_kgm2": 0.01, "n_rdot": 0.0}, "not positive definite"),
        ({"y_rdot": 1.0}, "must be symmetric"),
        ({"xu": math.nan}, "xu must be finite"),
    ],
)
def test_invalid_configuration_refused(change: dict[str, float], match: str) -> None:
    with pytest.raises(VesselConfigError, match=match):
        replace(P, **change)  # type: ignore[arg-type]


def test_params_kernel_arrays_respect_damping_switch() -> None:
    _, coef = VesselParams(damping_enabled=False).kernel_arrays()
    assert np.all(damping_matrix(coef, np.array([0.2, 0.1, 0.3])) == 0.0)
