"""Exceptions of the simulated world (the vessel model's own live in :mod:`hil.model.errors`)."""

from hil.model.errors import SimError


class ClosedLoopConfigError(SimError, ValueError):
    """Invalid settings of the compiled closed loop."""
