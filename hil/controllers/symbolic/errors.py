"""Errors of the symbolic controller (grid, abstraction, synthesis, controller files)."""

from __future__ import annotations

__all__ = [
    "ControllerFileError",
    "EmptyInputSetError",
    "GridError",
    "NoWinningSetError",
    "SymbolicError",
]


class SymbolicError(ValueError):
    """Base class of every error raised by :mod:`hil.controllers.symbolic`."""


class GridError(SymbolicError):
    """A grid or set that cannot be abstracted (bad widths, a target with no whole cell)."""


class NoWinningSetError(SymbolicError):
    """Synthesis found no winning cell outside the target, or no target cell at all."""


class ControllerFileError(SymbolicError):
    """A saved controller that cannot be read: missing, corrupt or of another version."""


class EmptyInputSetError(SymbolicError):
    """Selection was asked to choose from an empty set of safe inputs."""
