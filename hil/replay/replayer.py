"""Replay a recorded run through the current code and compare it with the recording.

Open loop (default), four checks, each in its own module:

- ``decisions``: at every recorded decision, the controller for the recorded
  obstacle layout is synthesized anew with the current code (one per distinct
  layout, cached) and queried at the recorded estimated state: cell, winning
  status, value, safe-input set and the input the paper's J picks given the
  previous recorded choice. Any difference is a regression.
- ``tracking``: velocity-tracking error per axis (RMS, max) of the recorded
  estimates (odometry) against the recorded references: figures beside the
  paper's tank figures, FAIL only above thresholds ``--tolerance`` sets.
- ``contract``: every interval between decisions held to its decision's contract
  (:mod:`hil.replay.intervals`): each estimate sample within the estimation bound of
  the tube, the next decision's estimate in the successor cells with a smaller value,
  |nu_hat - nu_ref| within the transient budget's envelope; FAIL naming the interval
  and the size of each violation.
- ``stack``: the full stack (observer, decisions, PID, allocation) re-run by
  :class:`hil.runtime.loop.Runtime` on the recorded sensor and obstacle streams
  through the ``log`` adapters; its estimates, decisions, references, thruster
  commands and tracking error must reproduce the recording (not judged, SKIP,
  for a run over ROS, whose per-tick sample arrival is not recorded), up to a
  decision the re-run took the other way at a cell boundary or cost tie within
  tolerance: accepted, reported, and nothing after it compared.

A bag holding only the lab's topics (no ``/hil/...`` topic, no hil metadata) is
replayed by :mod:`hil.replay.lab` instead: the stack re-run on its pose and IMU, its
decisions reported, tracking judged from what the bag holds, and what cannot be
judged without hil's topics said in the report's notes.

With ``ReplayOptions.intervals`` the judged intervals (sizes, tracking error, verdict)
are kept in the report as well.

Closed loop (``resim``): the recorded scenario, seed and start (from the suite
manifest beside the log when there is one, else the first recorded pose) are
simulated again with the current code and the trajectory, decisions and
tracking error compared with the recording (up to a decision taken the other way
within tolerance, as for ``stack``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from hil.bag.errors import ReplayError
from hil.bag.run_data import RunData, load_run
from hil.controllers.symbolic import SymbolicError
from hil.replay.context import ReplayCheck, ReplayContext
from hil.replay.controllers import ScenarioCache, ScenarioMismatchError, resolve_scenario
from hil.replay.decisions import check_decisions
from hil.replay.estimation_check import check_estimation
from hil.replay.intervals import check_contract
from hil.replay.lab import NOT_JUDGED, lab_topics, replay_lab, require_pose
from hil.replay.options import ReplayOptions
from hil.replay.qtm_check import check_qtm, has_qtm
from hil.replay.regression import Check, LogReport
from hil.replay.resim import check_resim
from hil.replay.stack_rerun import check_stack
from hil.replay.stop_check import check_stop
from hil.replay.tracking_checks import check_tracking
from hil.scenarios import ScenarioError


def replay_log(
    path: str | Path,
    options: ReplayOptions | None = None,
    caches: ScenarioCache | None = None,
    progress: Callable[[str], None] | None = None,
) -> LogReport:
    """Replay one log and return its report; never raises for a bad or foreign log.

    Args:
        path: Bag directory or ``.mcap`` file; never modified.
        options: What to check and with which thresholds.
        caches: Controllers shared with other logs of the same replay.
        progress: Called with the name of each step as it starts ("load",
            "decisions", ...), for a progress display.
    """
    options = options or ReplayOptions()
    caches = caches or ScenarioCache(options.cache_dir)
    step = progress or (lambda _name: None)
    wall = time.perf_counter()
    try:
        step("load")
        run = load_run(path, options.lab or lab_topics())
        if run.lab_only:
            return _replay_lab(run, options, caches, step, wall)
        scenario = resolve_scenario(run, options.scenario)
        ctx = ReplayContext(run, scenario, caches, options)
        checks: tuple[Check, ...] = ()
        for entry in CHECKS:
            if entry.wanted(options) and entry.applies(run):
                step(entry.name)
                checks += (entry.check(ctx.after(checks)),)
    except _REFUSED as err:
        return _error(path, err, wall)
    intervals = tuple(i for c in checks for i in c.intervals) if options.intervals else ()
    return LogReport(str(path), checks, run.warnings, "", time.perf_counter() - wall, intervals)


def _always(_options: ReplayOptions) -> bool:
    return True


def _any_run(_run: RunData) -> bool:
    return True


@dataclass(frozen=True)
class CheckEntry:
    """One check of the replay and when it is made.

    Attributes:
        name: The check's name (the progress step and ``Check.name``).
        check: Makes it.
        wanted: Whether the options ask for it.
        applies: Whether the run holds what it checks (else it is left out, not SKIP).
    """

    name: str
    check: ReplayCheck
    wanted: Callable[[ReplayOptions], bool] = _always
    applies: Callable[[RunData], bool] = _any_run


CHECKS: tuple[CheckEntry, ...] = (
    CheckEntry("decisions", check_decisions),
    CheckEntry("tracking", check_tracking),
    CheckEntry("stack", check_stack, lambda o: o.stack),
    CheckEntry("resim", check_resim, lambda o: o.resim),
    CheckEntry("contract", check_contract),
    CheckEntry("stop", check_stop),
    CheckEntry("estimation", check_estimation),
    CheckEntry("qtm", check_qtm, applies=has_qtm),
)
"""The checks of a hil log, in order (the contract marks intervals the earlier ones failed)."""


_REFUSED = (ReplayError, SymbolicError, ScenarioError, ValueError, OSError)
"""What makes a log unreadable (ERROR, exit 2) rather than a regression."""


def _error(path: str | Path, err: BaseException, wall: float) -> LogReport:
    message = str(err).splitlines()[0] if str(err) else type(err).__name__
    return LogReport(str(path), error=message, wall_s=time.perf_counter() - wall)


def _replay_lab(
    run: RunData,
    options: ReplayOptions,
    caches: ScenarioCache,
    step: Callable[[str], None],
    wall: float,
) -> LogReport:
    """Replay a bag holding only the lab's topics (:mod:`hil.replay.lab`)."""
    if options.scenario is None:
        raise ScenarioMismatchError(
            f"{str(run.path)!r} holds only the lab's topics (no hil metadata), so it names no "
            "scenario: pass --scenario NAME (e.g. paper, coarse or a TOML path)"
        )
    scenario = resolve_scenario(run, options.scenario)
    require_pose(run)
    step("stack")
    checks, intervals, decisions = replay_lab(
        ReplayContext(run, scenario, caches, options), options.lab_loop
    )
    notes = (
        f"a lab bag (only the lab's topics), replayed with scenario {options.scenario!r}",
        *run.notes,
        *(f"not judged without hil's topics: {line}" for line in NOT_JUDGED),
    )
    return LogReport(
        str(run.path),
        tuple(checks),
        run.warnings,
        "",
        time.perf_counter() - wall,
        intervals if options.intervals else (),
        notes,
        decisions,
    )
