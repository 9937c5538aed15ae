"""The vessel model (layer 1): 3-DOF C/S Enterprise I dynamics, thrusters, environment.

Pure physics of the hull and its actuators, with the published coefficients
(``shared/VESSEL.md``). Imports only :mod:`hil.core`; the controllers (which use the
model for feed-forward and allocation) and the simulator build on it.
"""

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
from hil.model.vessel import (
    ENTERPRISE_I,
    Integrator,
    Vessel,
    VesselParams,
    VesselState,
)

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
