"""The vessel model (layer 1): 3-DOF C/S Enterprise I dynamics, thrusters, environment.

Pure physics of the hull and its actuators, with the published coefficients
(``shared/VESSEL.md``): :mod:`~hil.model.coefficients` (the hull's coefficients and
their kernel layout), :mod:`~hil.model.dynamics` (the compiled 3-DOF kernels),
:mod:`~hil.model.vessel` (the checked Python face), :mod:`~hil.model.thrusters`,
:mod:`~hil.model.environment`. Imports only :mod:`hil.core`; the controllers (which use the
model for feed-forward and allocation) and the simulator build on it.
"""

from hil.model.coefficients import ENTERPRISE_I, VesselParams
from hil.model.dynamics import Integrator
from hil.model.environment import EnvironmentalLoad
from hil.model.errors import (
    EnvironmentConfigError,
    NonFiniteCommandError,
    NonFiniteForceError,
    SimError,
    StateShapeError,
    VesselConfigError,
)
from hil.model.thrusters import VOYAGER_THRUSTERS, ThrusterParams, Thrusters, ThrusterState
from hil.model.vessel import Vessel, VesselState

__all__ = [
    "ENTERPRISE_I",
    "VOYAGER_THRUSTERS",
    "EnvironmentConfigError",
    "EnvironmentalLoad",
    "Integrator",
    "NonFiniteCommandError",
    "NonFiniteForceError",
    "SimError",
    "StateShapeError",
    "ThrusterParams",
    "ThrusterState",
    "Thrusters",
    "Vessel",
    "VesselConfigError",
    "VesselParams",
    "VesselState",
]
