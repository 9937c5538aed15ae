"""Errors of the scenario layer."""

from __future__ import annotations

from hil.core.config import ConfigError

__all__ = ["ScenarioError"]


class ScenarioError(ConfigError):
    """A scenario that cannot be used; the message names the key and the problem.

    A :class:`~hil.core.config.ConfigError` (and so a ``ValueError``): a scenario
    file is a configuration file, checked by the same key and type rules.
    """
