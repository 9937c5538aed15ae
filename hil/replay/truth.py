"""The guarantee judged on a true trajectory recorded outside hil (issue 11's outside check).

A vessel simulator that hil did not write (``tools/independent_vessel.py``, or a lab's
own) records its true state while ``hil vessel`` drives it over ROS 2. This module
reads that file, maps it from the lab's frame to the arena with the vessel config's
transform, resamples it onto a uniform grid and holds the run's recorded decisions to
it with :func:`hil.runs.guarantee.judge_run`, the judge of the campaigns; the
controllers are re-synthesized from the recorded layouts, as ``hil replay`` does.

Truth file: CSV with a header row and one row per true state; ``t_ns`` (integer
nanoseconds on the clock of the run's message stamps: ``/clock`` in sim time, the
epoch in wall time) and either ``north_m, east_m, yaw_rad`` (the lab's ``world_ned``,
the pose of the mocap rigid body the pose topic reports) or ``x_m, y_m, psi_rad`` (the
arena frame, the vessel's body origin). Other columns (velocities) are ignored.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hil.adapters.frames import ArenaTransform
from hil.bag.errors import ReplayError
from hil.bag.run_data import RunData, load_run
from hil.controllers.symbolic import Controller
from hil.core.arrays import FloatArray, IntArray
from hil.core.clock import NS_PER_S
from hil.core.geometry import wrap_angles
from hil.core.samples import Frame, PoseSample
from hil.replay.controllers import ControllerCache, resolve_scenario
from hil.replay.decisions import decision_controllers
from hil.runs.guarantee import GuaranteeViolations, judge_run

__all__ = ["TrueTrajectory", "TruthError", "TruthJudgement", "judge_log_on_truth", "load_truth"]


_COLUMNS = {
    Frame.LAB_NED: ("north_m", "east_m", "yaw_rad"),
    Frame.ARENA: ("x_m", "y_m", "psi_rad"),
}


class TruthError(ReplayError, ValueError):
    """A true-state file that cannot be read or does not cover the run."""


@dataclass(frozen=True)
class TrueTrajectory:
    """True poses of a vessel over time, in one frame.

    Attributes:
        t_ns: Times (ns on the run's clock), shape (N,), strictly increasing.
        eta: Poses, shape (N, 3) indexed [time, axis]: (x m, y m, heading rad) in
            `frame` (north, east, yaw for the lab's NED world).
        frame: :attr:`Frame.LAB_NED` or :attr:`Frame.ARENA`.
    """

    t_ns: IntArray
    eta: FloatArray
    frame: Frame

    def to_arena(self, transform: ArenaTransform) -> TrueTrajectory:
        """Return the trajectory in the arena frame (the vessel's body origin)."""
        if self.frame is Frame.ARENA:
            return self
        out = np.empty_like(self.eta)
        for n, (t_ns, (north, east, yaw)) in enumerate(zip(self.t_ns, self.eta, strict=True)):
            pose = transform.to_arena(
                PoseSample(int(t_ns), float(north), float(east), float(yaw), Frame.LAB_NED))
            out[n] = (pose.x_m, pose.y_m, pose.yaw_rad)
        return TrueTrajectory(self.t_ns, out, Frame.ARENA)

    def at(self, t_ns: IntArray) -> FloatArray:
        """Return the poses linearly interpolated at times `t_ns` (M,), shape (M, 3).

        The heading is interpolated along its unwrapped path and wrapped back.
        """
        t = (self.t_ns - self.t_ns[0]).astype(np.float64)
        q = (np.asarray(t_ns, dtype=np.int64) - self.t_ns[0]).astype(np.float64)
        heading = np.unwrap(self.eta[:, 2])
        return np.stack([np.interp(q, t, self.eta[:, 0]), np.interp(q, t, self.eta[:, 1]),
                         wrap_angles(np.interp(q, t, heading))], axis=1)

    def resampled(self, dt_s: float) -> tuple[FloatArray, FloatArray]:
        """Return times (s) and poses on a uniform grid of `dt_s` from the first state.

        Returns:
            t_s (M,) on the run's clock and eta (M, 3), what :func:`judge_run` takes.
        """
        dt_ns = round(dt_s * NS_PER_S)
        grid = np.arange(int(self.t_ns[0]), int(self.t_ns[-1]) + 1, dt_ns, dtype=np.int64)
        return grid.astype(np.float64) / NS_PER_S, self.at(grid)


def load_truth(path: str | Path) -> TrueTrajectory:
    """Read a true-state CSV file (see the module's docstring).

    Raises:
        TruthError: The file is missing, has no known columns, a non-finite value, fewer
            than two rows or times that do not increase.
    """
    path = Path(path)
    try:
        with path.open(newline="") as fh:
            reader = csv.DictReader(fh)
            header = reader.fieldnames or []
            frame = next((f for f, cols in _COLUMNS.items() if set(cols) <= set(header)), None)
            if "t_ns" not in header or frame is None:
                raise TruthError(
                    f"{str(path)!r}: the header {header!r} names neither t_ns, north_m, "
                    "east_m, yaw_rad (world_ned) nor t_ns, x_m, y_m, psi_rad (arena)")
            names = _COLUMNS[frame]
            t_ns, rows = [], []
            for line, row in enumerate(reader, start=2):
                try:
                    t_ns.append(int(row["t_ns"]))
                    rows.append([float(row[c]) for c in names])
                except (TypeError, ValueError) as err:
                    raise TruthError(f"{str(path)!r} line {line}: {err}") from err
    except OSError as err:
        raise TruthError(f"cannot read the true-state file {str(path)!r}: {err}") from err
    times = np.asarray(t_ns, dtype=np.int64)
    eta = np.asarray(rows, dtype=np.float64).reshape(-1, 3)
    if len(times) < 2:
        raise TruthError(f"{str(path)!r} holds {len(times)} true state(s); at least 2 needed")
    if not np.all(np.isfinite(eta)):
        raise TruthError(f"{str(path)!r} holds a non-finite pose")
    if not np.all(np.diff(times) > 0):
        raise TruthError(f"{str(path)!r}: t_ns must increase strictly")
    return TrueTrajectory(times, eta, frame)


@dataclass(frozen=True, slots=True)
class TruthJudgement:
    """A recorded run judged on an outside true trajectory.

    Attributes:
        violations: The guarantee's counts and worst sizes on the true state.
        unjudged: One line per decision whose contract could not be rebuilt (judged
            for safety only).
        pose_offset_m: Largest distance between a pose the stack received (mapped to
            the arena by its transform) and the true pose at its stamp (m): noise, unless
            frames, transform or clocks disagree.
        heading_offset_rad: The same for the heading (rad).
    """

    violations: GuaranteeViolations
    unjudged: tuple[str, ...]
    pose_offset_m: float
    heading_offset_rad: float


def _pose_offsets(run: RunData, truth: TrueTrajectory) -> tuple[float, float]:
    """Return the largest (position m, heading rad) gap of the received poses to the truth."""
    inside = (run.pose.t_ns >= truth.t_ns[0]) & (run.pose.t_ns <= truth.t_ns[-1])
    if not inside.any():
        return math.inf, math.inf
    received = run.pose.values[inside]
    true = truth.at(run.pose.t_ns[inside])
    position = float(np.hypot(*(received[:, :2] - true[:, :2]).T).max())
    heading = float(np.abs(wrap_angles(received[:, 2] - true[:, 2])).max())
    return position, heading


def judge_log_on_truth(
    log: str | Path,
    truth: TrueTrajectory,
    transform: ArenaTransform,
    *,
    dt_s: float = 0.01,
    tick_s: float = 0.05,
    controllers: ControllerCache | None = None,
) -> TruthJudgement:
    """Judge a recorded run's decisions against a true trajectory recorded beside it.

    Args:
        log: The run's bag (``hil vessel``'s recording).
        truth: The true trajectory, in the lab frame or the arena's.
        transform: The vessel config's ``[ros.transform]`` (lab to arena).
        dt_s: Step of the uniform grid the truth is resampled onto (s).
        tick_s: The run's loop period (s): intervals longer than tau + tick_s / 2 are late.
        controllers: The scenario's controllers (re-synthesized per recorded layout);
            default: a fresh cache (pass one to share syntheses between runs).

    Returns:
        The counts and worst sizes, what could not be judged, and how far the received
        poses lie from the truth.

    Raises:
        TruthError: The truth does not cover the run's decisions.
        hil.bag.errors.ReplayError: The log cannot be read or its scenario loaded.
    """
    run = load_run(log)
    scenario = resolve_scenario(run)
    arena = truth.to_arena(transform)
    if run.decisions:
        first, last = run.decisions[0].t_ns, run.decisions[-1].t_ns
        if arena.t_ns[0] > first or arena.t_ns[-1] < last:
            raise TruthError(
                f"the true states span t_ns {int(arena.t_ns[0])}..{int(arena.t_ns[-1])}, the "
                f"decisions {first}..{last}: not the same clock, or not the same run?")
    if controllers is None or controllers.scenario != scenario:
        controllers = ControllerCache(scenario)
    by_version: dict[int, Controller] = {}
    unjudged: list[str] = []
    for decision, got in decision_controllers(run, controllers):
        if isinstance(got, str):
            unjudged.append(f"decision at t={decision.t_ns} ns: {got}")
        else:
            by_version.setdefault(decision.controller_version, got.controller)
    t_s, eta = arena.resampled(dt_s)
    violations = judge_run(scenario, run.decisions, by_version, t_s, eta, tick_s=tick_s)
    position, heading = _pose_offsets(run, arena)
    return TruthJudgement(violations, tuple(unjudged), position, heading)
