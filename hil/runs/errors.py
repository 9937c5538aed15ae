"""Exceptions of the run executors and the results stream."""

from __future__ import annotations

__all__ = ["ExecutorError", "ResultsError"]


class ExecutorError(RuntimeError):
    """An executor cannot be used: Dask not installed, no scheduler at the address, no workers."""


class ResultsError(ValueError):
    """A results file cannot be written, or resumed (of another campaign, not a results file)."""
