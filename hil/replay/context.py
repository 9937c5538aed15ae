"""What every replay check is given, and the one shape of a check.

A check takes a :class:`ReplayContext` (the run, its scenario, the current code's
controllers for it, the options, and the checks already made on the log) and returns
one :class:`~hil.replay.regression.Check`. The replayer runs them from one table
(:data:`hil.replay.replayer.CHECKS`), the lab-bag replay the ones that apply to it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Protocol

from hil.bag.run_data import RunData
from hil.replay.controllers import ControllerCache, ScenarioCache
from hil.replay.options import ReplayOptions
from hil.replay.regression import Check
from hil.scenarios import Scenario

__all__ = ["ReplayCheck", "ReplayContext"]


@dataclass(frozen=True)
class ReplayContext:
    """The inputs of a replay check.

    Attributes:
        run: The recorded run.
        scenario: Its scenario (recorded, or the one given for a lab bag).
        caches: The current code's controllers, shared by the logs of one replay.
        options: What to check and with which thresholds.
        earlier: The checks already made on this log, in order (a failed one marks its
            interval in the contract check).
    """

    run: RunData
    scenario: Scenario
    caches: ScenarioCache
    options: ReplayOptions = field(default_factory=ReplayOptions)
    earlier: tuple[Check, ...] = ()

    @property
    def controllers(self) -> ControllerCache:
        """The controllers of the scenario's layouts (its tables loaded on first use)."""
        return self.caches.get(self.scenario)

    def after(self, checks: tuple[Check, ...]) -> ReplayContext:
        """Return this context with `checks` as the ones already made."""
        return replace(self, earlier=checks)

    def on(self, run: RunData) -> ReplayContext:
        """Return this context for another view of the run (a lab bag's re-run)."""
        return replace(self, run=run)


class ReplayCheck(Protocol):
    """A replay check: the context in, one check's outcome out."""

    def __call__(self, ctx: ReplayContext) -> Check:
        """Make the check on `ctx.run`."""
        ...
