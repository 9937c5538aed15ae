"""Turn a recorded run into a Rerun recording: arena, vessel, controller view, time series.

Every Rerun call of hil lives in :mod:`hil.views` (the Rerun API moves fast):
this module writes a recorded run to an ``.rrd`` or a viewer; one
``log_<stream>()`` per stream in :mod:`hil.views.rerun_world` (arena frame) and
:mod:`hil.views.rerun_plots` (time series); whole series go out with
``send_columns`` on the run's own time axis (:data:`hil.views.rerun_style.TIMELINE`,
the run clock as a duration), calibration and the arena with ``static=True``;
:func:`hil.views.blueprint.blueprint` lays the viewer out and
:mod:`hil.views.rerun_live` streams a run while it goes on.

Entity paths mirror frames:

- ``world``: the arena frame, shown top-down like the paper's figures (x right,
  y up); ``world/arena/{boundary,target/T1,target/T2,obstacles/real,obstacles/inflated}``;
- ``world/vessel``: the body frame, one transform per measured pose; its child
  ``world/vessel/hull`` is the hull outline in the body frame;
- ``world/pose_samples``, ``world/trajectory``: the measured poses and the
  estimated path, in the arena frame;
- ``world/controller/{safe_inputs,chosen_input,winning_set}``: the controller's
  view at each decision;
- ``plots/...``: velocity per axis, tracking error with the velocity envelope band,
  thrusters, azimuth angles, force, value, synthesis time, QTM's frames as received
  (``plots/qtm/...``, qtm backend runs); ``events``: faults.
"""

from __future__ import annotations

import os
import shutil
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import rerun as rr

from hil.bag.run_data import RunData
from hil.core.records import Decision
from hil.scenarios import Scenario
from hil.views.blueprint import blueprint
from hil.views.controller_view import ControllerView
from hil.views.rerun_plots import (
    log_events,
    log_force,
    log_qtm,
    log_synthesis_time,
    log_thrusters,
    log_tracking_error,
    log_value,
    log_velocity,
)
from hil.views.rerun_style import APPLICATION_ID, log_styles
from hil.views.rerun_world import (
    log_arena,
    log_decisions,
    log_obstacles,
    log_pose_samples,
    log_replayed_decisions,
    log_trajectory,
    log_vessel,
    log_winning_set,
)


@dataclass(frozen=True, slots=True)
class ExportStats:
    """What an export wrote.

    Attributes:
        path: The ``.rrd`` file (None when streamed to a viewer).
        bytes: File size (bytes; 0 when streamed).
        rows: Rows sent over all entities.
        seconds: Wall time of the export (s).
    """

    path: Path | None
    bytes: int
    rows: int
    seconds: float


def log_run(
    rec: rr.RecordingStream,
    run: RunData,
    scenario: Scenario | None,
    view: ControllerView | None,
    replayed: Sequence[Decision] | None = None,
) -> int:
    """Log every stream of `run` (and `replayed` decisions beside) to `rec`; return the rows."""
    tau_s = scenario.tau_s if scenario is not None else 2.0
    budget = scenario.transient if scenario is not None else None
    rows = log_styles(rec)
    rows += log_arena(rec, scenario)
    rows += log_obstacles(rec, run, scenario)
    rows += log_vessel(rec, run, scenario)
    rows += log_pose_samples(rec, run)
    rows += log_trajectory(rec, run)
    rows += log_decisions(rec, run, tau_s)
    if view is not None:
        rows += log_winning_set(rec, run, view)
    rows += log_velocity(rec, run)
    rows += log_tracking_error(rec, run, budget)
    rows += log_thrusters(rec, run)
    rows += log_force(rec, run)
    rows += log_value(rec, run)
    rows += log_synthesis_time(rec, run)
    rows += log_events(rec, run)
    rows += log_qtm(rec, run)
    if replayed is not None:
        rows += log_replayed_decisions(rec, run.decisions, replayed, tau_s)
    return rows


def _recording(run: RunData) -> rr.RecordingStream:
    name = run.path.name or str(run.path)
    return rr.RecordingStream(
        APPLICATION_ID, recording_id=f"{name}-{run.start_ns}-{run.end_ns}", send_properties=False
    )


def write_rrd(
    run: RunData,
    path: str | Path,
    scenario: Scenario | None,
    view: ControllerView | None,
    replayed: Sequence[Decision] | None = None,
) -> ExportStats:
    """Write the run to an ``.rrd`` file with its blueprint.

    Args:
        run: The recorded run.
        path: The ``.rrd`` file to write (replaced if it exists).
        scenario: The run's scenario (arena, hull, tau, transient budget); None when unknown.
        view: The controller's view per decision; None to leave out the winning set.
        replayed: Decisions of a replay of the run, shown beside the recorded ones
            with their differences marked (``hil replay LOG --rerun``); None for none.

    Returns:
        What was written.

    Raises:
        RrdWriteError: The file cannot be created.
    """
    start = time.perf_counter()
    out = Path(path)
    if not out.parent.is_dir():
        raise RrdWriteError(f"cannot write {str(out)!r}: {str(out.parent)!r} is not a folder")
    rec = _recording(run)
    try:
        rec.save(out, default_blueprint=blueprint(scenario, replay=replayed is not None))
    except RuntimeError as err:
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise RrdWriteError(f"cannot write {str(out)!r}: {first}") from err
    rows = log_run(rec, run, scenario, view, replayed)
    rec.flush()
    rec.disconnect()
    return ExportStats(out, out.stat().st_size, rows, time.perf_counter() - start)


class ViewerError(RuntimeError):
    """The Rerun viewer cannot be started."""


class RrdWriteError(OSError):
    """An ``.rrd`` file cannot be written (its message names the path)."""


def start_viewer(rec: rr.RecordingStream, scenario: Scenario | None) -> None:
    """Start a viewer and connect `rec` to it.

    Raises:
        ViewerError: The viewer executable is missing or does not start.
    """
    # An un-activated virtual environment has the viewer beside its python, not on PATH.
    beside = Path(sys.executable).with_name("rerun")
    if shutil.which("rerun") is None and beside.is_file():
        os.environ["PATH"] = f"{beside.parent}{os.pathsep}{os.environ.get('PATH', '')}"
    try:
        rec.spawn(default_blueprint=blueprint(scenario))
    except RuntimeError as err:
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise ViewerError(f"cannot start the Rerun viewer: {first}") from err


def spawn_viewer(
    run: RunData, scenario: Scenario | None, view: ControllerView | None
) -> ExportStats:
    """Open the Rerun viewer and stream the run to it.

    Raises:
        ViewerError: The viewer cannot be started.
    """
    start = time.perf_counter()
    rec = _recording(run)
    start_viewer(rec, scenario)
    rows = log_run(rec, run, scenario, view)
    try:
        rec.flush(timeout_sec=30.0)
    except RuntimeError as err:
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise ViewerError(f"the Rerun viewer did not take the run: {first}") from err
    return ExportStats(None, 0, rows, time.perf_counter() - start)
