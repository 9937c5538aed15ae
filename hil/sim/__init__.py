"""The simulated C/S Voyager: 3-DOF vessel model, thrusters, environment, low-level loop.

Public names below come from :mod:`hil.sim.vessel`, :mod:`hil.sim.environment`,
:mod:`hil.sim.thrusters` and :mod:`hil.sim.errors`. The compiled closed loop lives
in :mod:`hil.sim.closed_loop` and the sensor models in :mod:`hil.sim.sensors`;
import those by their full path (the closed loop depends on :mod:`hil.controllers`,
which depends on this package).
"""

from hil.sim.environment import EnvironmentalLoad
from hil.sim.errors import (
    ClosedLoopConfigError,
    EnvironmentConfigError,
    NonFiniteCommandError,
    NonFiniteForceError,
    SimError,
    StateShapeError,
    VesselConfigError,
)
from hil.sim.thrusters import VOYAGER_THRUSTERS, ThrusterParams, Thrusters, ThrusterState
from hil.sim.vessel import (
    ENTERPRISE_I,
    Integrator,
    Vessel,
    VesselParams,
    VesselState,
)

__all__ = [
    "ENTERPRISE_I",
    "VOYAGER_THRUSTERS",
    "ClosedLoopConfigError",
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
