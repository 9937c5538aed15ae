"""The controllers a replay compares against: synthesized with the current code.

One controller per distinct obstacle layout (:class:`ControllerCache`), shared by
the logs of one replay per scenario (:class:`ScenarioCache`); the scenario a log
was recorded with is found and checked by its hash (:func:`resolve_scenario`).
"""

from __future__ import annotations

from pathlib import Path

from hil.bag.errors import ReplayError
from hil.bag.run_data import RunData
from hil.controllers.symbolic import NoWinningSetError, SymbolicAdapter, Synthesizer
from hil.core.samples import ObstacleLayout
from hil.core.shapes import Rect
from hil.runs.stack_assembly import scenario_hash, synthesizer_for
from hil.runtime.assembly import LayoutSolver
from hil.runtime.controller_lru import ControllerLru
from hil.scenarios import Scenario, ScenarioError, load_scenario


class ScenarioMismatchError(ReplayError, ValueError):
    """The log was recorded for another scenario than the one it would be replayed with."""


class ControllerCache:
    """One controller per distinct obstacle layout and report age, with the current code.

    The controllers kept are bounded in bytes (:class:`ControllerLru`): a log with moving
    obstacles has a layout per report, and a dropped one is read back from the store.

    Callable as a solver for :class:`hil.runtime.resynthesis.Resynthesizer`.

    Args:
        scenario: The scenario (grid, inputs, target, inflation).
        cache_dir: Abstraction-table cache.
    """

    def __init__(self, scenario: Scenario, cache_dir: Path | None = None) -> None:
        self.scenario = scenario
        self._solver = LayoutSolver(scenario, synthesizer_for(scenario, cache_dir))
        self._done: ControllerLru[SymbolicAdapter | NoWinningSetError] = ControllerLru()
        self._seen: set[tuple[tuple[Rect, ...], float]] = set()
        self.layouts = 0

    @property
    def synthesizer(self) -> Synthesizer:
        """The synthesizer holding the scenario grid's abstraction tables."""
        return self._solver.synthesizer

    def __call__(
        self, layout: ObstacleLayout, report_age_s: float | None = None
    ) -> SymbolicAdapter:
        """Return the controller for `layout`, moving obstacles grown for `report_age_s`.

        None: the scenario's ``max_report_age_s`` (a decision of a log written before
        the age was recorded).

        Raises:
            NoWinningSetError: The layout leaves no winning set.
        """
        age = self.scenario.tracking.max_report_age_s if report_age_s is None else report_age_s
        key = (layout.obstacles, age)
        got = self._done.get(key)
        if got is None:
            if key not in self._seen:
                self._seen.add(key)
                self.layouts += 1
            try:
                got = self._solver(layout, age)
            except NoWinningSetError as err:
                got = err
            self._done.put(key, got, None if isinstance(got, NoWinningSetError) else got.controller)
        if isinstance(got, NoWinningSetError):
            raise got
        return got


class ScenarioCache:
    """Controller caches keyed by scenario hash, shared by the logs of one replay."""

    def __init__(self, cache_dir: Path | None = None) -> None:
        self._cache_dir = cache_dir
        self._caches: dict[str, ControllerCache] = {}

    def get(self, scenario: Scenario) -> ControllerCache:
        """Return the cache of `scenario`, created on first use."""
        key = scenario_hash(scenario)
        if key not in self._caches:
            self._caches[key] = ControllerCache(scenario, self._cache_dir)
        return self._caches[key]


def resolve_scenario(run: RunData, override: str | None = None) -> Scenario:
    """Return the scenario the log was recorded with, checked by its hash.

    Raises:
        ScenarioMismatchError: The log names no scenario, names one that cannot be
            loaded, or was recorded for another scenario content.
    """
    info = run.info.run
    recorded_hash = info.scenario_hash if info is not None else ""
    hashes = {d.scenario_hash for d in run.decisions}
    if not recorded_hash and len(hashes) == 1:
        recorded_hash = next(iter(hashes))
    name = override or (info.scenario_file if info is not None else "")
    if not name:
        raise ScenarioMismatchError(
            f"{str(run.path)!r} names no scenario (no hil metadata); pass --scenario"
        )
    try:
        scenario = load_scenario(name)
    except ScenarioError as err:
        raise ScenarioMismatchError(
            f"{str(run.path)!r} was recorded with scenario {name!r}, which cannot be loaded: {err}"
        ) from err
    current = scenario_hash(scenario)
    if recorded_hash and current != recorded_hash:
        raise ScenarioMismatchError(
            f"{str(run.path)!r} was recorded for scenario hash {recorded_hash!r}, but "
            f"{name!r} now hashes to {current!r}: a log from another scenario (or the scenario "
            "changed; regenerate the suite with `hil record-suite`)"
        )
    if len(hashes) > 1:
        raise ScenarioMismatchError(
            f"{str(run.path)!r} mixes decisions of scenarios {sorted(hashes)!r}"
        )
    return scenario
