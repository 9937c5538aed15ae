"""Errors raised by the vessel simulator (model, thrusters, environment, closed loop)."""

from __future__ import annotations


class SimError(Exception):
    """Base class of every simulator error."""


class VesselConfigError(SimError, ValueError):
    """A vessel or thruster configuration that cannot describe a physical vessel."""


class EnvironmentConfigError(SimError, ValueError):
    """An environmental-load configuration that is invalid (negative std, bad period)."""


class NonFiniteForceError(SimError, ValueError):
    """A force or moment given to the model is NaN or infinite."""


class NonFiniteCommandError(SimError, ValueError):
    """A thruster command or azimuth angle is NaN or infinite."""


class StateShapeError(SimError, ValueError):
    """A state or series has the wrong shape or non-finite entries."""

