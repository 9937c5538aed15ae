"""Errors raised by the controller stack (observer, velocity PID, thrust allocation).

Each subclasses :class:`ControllerError`; those about bad values also subclass
``ValueError`` so callers may catch either.
"""

from __future__ import annotations


class ControllerError(Exception):
    """Base class of every controller-stack error."""


class ObserverError(ControllerError):
    """Base class of the state observer's errors."""


class ObserverConfigError(ObserverError, ValueError):
    """An observer configuration with a non-finite, negative or inconsistent value."""


class ObserverInputError(ObserverError, ValueError):
    """An argument the observer cannot use: wrong frame, wrong shape, non-finite start."""


class ObserverNotInitializedError(ObserverError, RuntimeError):
    """The estimate was asked for before any pose (or explicit start) initialized the filter."""


class AllocationError(ControllerError, ValueError):
    """Base class of thrust-allocation errors."""


class AllocationConfigError(AllocationError):
    """An allocator setting or a demand of the wrong shape."""


class NonFiniteDemandError(AllocationError):
    """A force demand that holds NaN or inf."""
