"""The summary of one run: what a user reads first, and its JSON form.

Tracking error is the paper's measure, computed by :mod:`hil.core.tracking`:
the vessel's velocity (the estimate on the vessel; the simulator's truth in sim)
minus the velocity reference in force, at every tick under control, RMS and
largest per axis, yaw in deg/s as the paper prints it.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from hil.controllers.symbolic import ControllerSources
from hil.core.arrays import FloatArray
from hil.core.tracking import TrackingSeries, for_display, tracking_error
from hil.runs.clearance import hull_clearance_series
from hil.runtime.stats import RunStats
from hil.scenarios import Scenario

PAPER_TRACKING_ERROR = (0.00768, 0.00431, 0.62108)
"""The paper's tank figures: surge m/s, sway m/s, yaw deg/s (labelled MSE there)."""


@dataclass(frozen=True, slots=True)
class TrackingError:
    """Velocity-tracking error per axis, as reported: yaw in deg/s like the paper.

    Attributes:
        rms: RMS of (nu - nu_ref): surge m/s, sway m/s, yaw deg/s.
        max_abs: Largest |nu - nu_ref| with the same units.
        samples: Number of samples it was computed over.
    """

    rms: tuple[float, float, float]
    max_abs: tuple[float, float, float]
    samples: int

    @staticmethod
    def of(series: TrackingSeries) -> TrackingError:
        """Summarize an error series of :func:`hil.core.tracking.tracking_error` (NaN if empty)."""
        rms = for_display(series.rms())
        peak = for_display(series.peak()[0])
        return TrackingError(
            (float(rms[0]), float(rms[1]), float(rms[2])),
            (float(peak[0]), float(peak[1]), float(peak[2])),
            len(series),
        )


@dataclass(frozen=True, slots=True)
class RunSummary:
    """What one run did.

    Attributes:
        scenario: Scenario name or path.
        seed: Seed of the simulated world (None on the vessel).
        backend: "sim" or "ros".
        docked: Whether the vessel reached and held the target.
        end_reason: Why the run ended.
        docking_time_s: Time from start to reaching the target (s), None if never.
        duration_s: Simulated (or wall) time of the run (s).
        wall_s: Wall-clock time the run took (s).
        min_clearance_m: Smallest distance between the hull and a real obstacle (m),
            each obstacle where it is at each step (moved ones included); zero means
            contact.
        hull_contacts: Number of physics steps with the hull touching an obstacle.
        decisions: Symbolic decisions taken.
        resyntheses: Controllers synthesized and swapped in (the first one included),
            whatever their source: solved, read from the store or served from memory.
        synthesis_mean_s: Mean synthesis time (s).
        synthesis_max_s: Largest synthesis time (s).
        not_winning_decisions: Decisions taken outside the winning set.
        rejected_samples: Sensor samples the observer refused.
        pose_losses: Times the pose feed went stale.
        tracking: Tracking error against the reference.
        period_jitter_p99_ms: 99th percentile of |tick period - nominal| (ms); zero
            in simulated time.
        overruns: Ticks that started more than one period late.
        log: Where the run's log is (None when not recorded).
        aborted: Whether the run stopped because it could not go on (synthesis
            failed, no safe input at the start); `end_reason` says why.
        tube_exits: Runtime monitor: estimates farther than the estimation bound from
            the decision's tube cells (each answered with a first decision).
        successor_misses: Runtime monitor: decisions whose estimate was outside the
            previous decision's successor cells.
        value_not_decreasing: Runtime monitor: decisions whose value was not below the
            previous decision's.
        worst_tube_exit_m: Largest of those tube distances (m).
        worst_successor_miss_m: Largest distance to the successor cells (m).
        moving_obstacles: Obstacles that moved during the run (the simulated world's
            scheduled motions); 0 when every obstacle stayed put.
        obstacle_stale_stops: Stops for an obstacle report too old to decide on
            (``obstacles_stale``).
        report_age_relied_s: With obstacles that move: the oldest a relied-on obstacle
            report was when a fresher one took over (s; 0: none measured).
        report_age_solved_s: The largest report age a controller in force was solved
            for (s; 0: obstacles fixed).
        brake_s: How long the vessel braked to rest under the low level after a stop
            (abort, operator, timeout) before the thrust was cut (s); None: no braking.
        late_intervals: Decisions later than tau + late after the previous one (a
            stalled loop: a broken premise, ``late_interval``); worst_late_s by how much (s).
        staying_decisions: Decisions taken on the safety controller (docking not
            winning, the vessel kept in the safety set); docking_lost the episodes.
        layout_waits: Waits at rest for a layout that wins (obstacles move; the state
            was outside the winning and the safety set).
        feed_rejections: On the vessel: per sensor topic with refused messages, what it
            delivered and refused by reason, with the fix (``FeedHealth.describe``).
        sources: Where the run's controllers came from (solved: the fixed point ran;
            store: read from the solved-controller store; memory: this process had
            solved the layout before); None when not counted (then only `resyntheses`).
    """

    scenario: str
    seed: int | None
    backend: str
    docked: bool
    end_reason: str
    docking_time_s: float | None
    duration_s: float
    wall_s: float
    min_clearance_m: float
    hull_contacts: int
    decisions: int
    resyntheses: int
    synthesis_mean_s: float
    synthesis_max_s: float
    not_winning_decisions: int
    rejected_samples: int
    pose_losses: int
    tracking: TrackingError
    period_jitter_p99_ms: float
    overruns: int
    log: str | None
    aborted: bool = False
    tube_exits: int = 0
    successor_misses: int = 0
    value_not_decreasing: int = 0
    worst_tube_exit_m: float = 0.0
    worst_successor_miss_m: float = 0.0
    moving_obstacles: int = 0
    obstacle_stale_stops: int = 0
    report_age_relied_s: float = 0.0
    report_age_solved_s: float = 0.0
    late_intervals: int = 0
    worst_late_s: float = 0.0
    brake_s: float | None = None
    staying_decisions: int = 0
    docking_lost: int = 0
    layout_waits: int = 0
    feed_rejections: tuple[str, ...] = ()
    sources: ControllerSources | None = None

    def to_json(self) -> str:
        """Return the summary as one line of JSON (NaN and inf as null)."""

        def clean(value: object) -> object:
            if isinstance(value, float) and not math.isfinite(value):
                return None
            if isinstance(value, dict):
                return {k: clean(v) for k, v in value.items()}
            if isinstance(value, list | tuple):
                return [clean(v) for v in value]
            return value

        data = clean(asdict(self))
        assert isinstance(data, dict)
        data["tracking_rms"] = data.pop("tracking")["rms"]
        data["tracking_max_abs"] = clean(list(self.tracking.max_abs))
        return json.dumps(data, sort_keys=True)

    def _controllers_row(self) -> tuple[str, str]:
        """Return the decisions and controllers row: solves apart from stored and memo hits."""
        if self.sources is None:
            return "decisions / re-syntheses", f"{self.decisions} / {self.resyntheses}"
        src = self.sources
        return (
            "decisions / controllers taken",
            f"{self.decisions} / {self.resyntheses}: {src.solved} solved, "
            f"{src.store} from the store, {src.memory} from memory",
        )

    def render(self, console: Console | None = None) -> None:
        """Print the summary as a table (rich)."""
        console = console or Console()
        verdict = "[bold green]DOCKED[/]" if self.docked else "[bold red]NOT DOCKED[/]"
        console.print(
            f"{verdict}  {self.scenario} (seed {self.seed}, {self.backend}): {self.end_reason}"
        )
        table = Table(show_header=True, header_style="bold")
        table.add_column("measure")
        table.add_column("value", justify="right")
        table.add_column("paper (tank)", justify="right")
        docking = (
            "-"
            if self.docking_time_s is None
            else (f"{self.docking_time_s:.1f} s ({self.docking_time_s / 60:.2f} min)")
        )
        table.add_row("docking time", docking, "2.67 min (1.71-3.66)")
        table.add_row("min hull clearance to real obstacles", f"{self.min_clearance_m:.3f} m", "-")
        table.add_row("hull contacts", str(self.hull_contacts), "0")
        table.add_row(*self._controllers_row(), "-")
        if self.moving_obstacles or self.obstacle_stale_stops:
            table.add_row("moving obstacles / stale-report stops",
                          f"{self.moving_obstacles} / {self.obstacle_stale_stops}", "-")
        if self.brake_s is not None:
            table.add_row("braked to rest after the stop", f"{self.brake_s:.1f} s", "-")
        if self.late_intervals:
            table.add_row("late intervals (worst, past tau + late)",
                          f"{self.late_intervals} ({self.worst_late_s:.3f} s)", "0")
        if self.report_age_solved_s:
            table.add_row("obstacle report age relied on / solved for (max)",
                          f"{self.report_age_relied_s:.2f} / {self.report_age_solved_s:g} s", "-")
        table.add_row(
            "synthesis time mean / max",
            f"{self.synthesis_mean_s * 1e3:.1f} / {self.synthesis_max_s * 1e3:.1f} ms",
            "~500 ms (GPU)",
        )
        labels = ("surge (m/s)", "sway (m/s)", "yaw (deg/s)")
        for label, rms, peak, paper in zip(
            labels, self.tracking.rms, self.tracking.max_abs, PAPER_TRACKING_ERROR, strict=True
        ):
            table.add_row(f"tracking RMS / max, {label}", f"{rms:.5f} / {peak:.4f}", f"{paper}")
        table.add_row("decisions outside winning set", str(self.not_winning_decisions), "-")
        if self.staying_decisions:
            table.add_row(
                "waited on the safety controller (docking lost)",
                f"{self.staying_decisions} decisions, {self.docking_lost} episode(s)",
                "-",
            )
        if self.layout_waits:
            table.add_row("waited at rest for a layout that wins", str(self.layout_waits), "-")
        table.add_row(
            "monitor: tube exits / successor misses / value not decreasing",
            f"{self.tube_exits} ({self.worst_tube_exit_m:.3f} m) / {self.successor_misses} "
            f"({self.worst_successor_miss_m:.3f} m) / {self.value_not_decreasing}",
            "-",
        )
        table.add_row(
            "rejected samples / pose losses", f"{self.rejected_samples} / {self.pose_losses}", "-"
        )
        table.add_row(
            "loop period jitter p99 / overruns",
            f"{self.period_jitter_p99_ms:.2f} ms / {self.overruns}",
            "-",
        )
        table.add_row(
            "run time (simulated / wall)", f"{self.duration_s:.1f} s / {self.wall_s:.2f} s", "-"
        )
        console.print(table)
        for line in self.feed_rejections:  # plain text: "[ros]" is no markup
            console.print(f"refused by the ROS backend: {line}", markup=False, highlight=False,
                          soft_wrap=True)
        if self.log is not None:
            console.print(f"log: {Path(self.log)}")


def summarize_run(
    *,
    scenario: Scenario,
    scenario_name: str,
    seed: int | None,
    backend: str,
    stats: RunStats,
    trajectory: FloatArray,
    velocity: FloatArray,
    wall_s: float,
    log: str | None,
    nominal_s: float = 0.05,
    obstacle_offsets_m: FloatArray | None = None,
    feed_rejections: tuple[str, ...] = (),
    sources: ControllerSources | None = None,
) -> RunSummary:
    """Summarize a finished run.

    Args:
        scenario: The scenario (real obstacles and hull for the clearance).
        scenario_name: Name or path as the user gave it.
        seed: Seed of the simulated world (None on the vessel).
        backend: "sim" or "ros".
        stats: The loop's counters and per-tick series.
        trajectory: Poses (x, y, psi) to judge clearance on, shape (N, 3) (the
            simulator's truth at every physics step, or the estimates on the vessel).
        velocity: Body velocity at each tick of `stats`, shape (len(stats.t_ns), 3).
        wall_s: Wall-clock duration (s).
        log: Where the run is recorded.
        nominal_s: The loop's nominal period (s).
        obstacle_offsets_m: Each obstacle's displacement from its scenario position at
            each pose of `trajectory` (m), shape (n_obstacles, N, 2); None: the obstacles
            stay put.
        feed_rejections: What the ROS backend refused, per topic (vessel runs).
        sources: Where the run's controllers came from; None when not counted.
    """
    clearance = hull_clearance_series(scenario, trajectory, obstacle_offsets_m)
    synth = stats.synthesis_seconds or [math.nan]
    reached = stats.target_reached_ns
    return RunSummary(
        scenario=scenario_name,
        seed=seed,
        backend=backend,
        docked=stats.docked_ns is not None,
        end_reason=stats.end_reason,
        docking_time_s=None if reached is None else (reached - stats.start_ns) / 1e9,
        duration_s=(stats.end_ns - stats.start_ns) / 1e9,
        wall_s=wall_s,
        min_clearance_m=float(clearance.min()) if len(clearance) else math.inf,
        hull_contacts=int(np.count_nonzero(clearance <= 0.0)),
        decisions=stats.decisions,
        resyntheses=stats.resyntheses,
        synthesis_mean_s=float(np.mean(synth)),
        synthesis_max_s=float(np.max(synth)),
        not_winning_decisions=stats.not_winning_decisions,
        rejected_samples=stats.rejected_samples,
        pose_losses=stats.pose_losses,
        tracking=_tracking(stats, velocity),
        period_jitter_p99_ms=period_jitter_p99_ms(stats.tick_wall_ns, nominal_s),
        overruns=stats.overruns,
        log=log,
        aborted=stats.aborted,
        tube_exits=stats.tube_exits,
        successor_misses=stats.successor_misses,
        value_not_decreasing=stats.value_not_decreasing,
        worst_tube_exit_m=stats.worst_tube_exit_m,
        worst_successor_miss_m=stats.worst_successor_miss_m,
        moving_obstacles=_moving_obstacles(obstacle_offsets_m),
        obstacle_stale_stops=stats.obstacle_stale_stops,
        report_age_relied_s=stats.report_age_relied_s,
        report_age_solved_s=stats.report_age_solved_s,
        late_intervals=stats.late_intervals,
        worst_late_s=stats.worst_late_s,
        brake_s=stats.brake_s,
        staying_decisions=stats.staying_decisions,
        docking_lost=stats.docking_lost,
        layout_waits=stats.layout_waits,
        feed_rejections=feed_rejections,
        sources=sources,
    )


def _moving_obstacles(offsets_m: FloatArray | None) -> int:
    """Return how many obstacles move: nonzero offsets (n_obstacles, N, 2) (m); None: none."""
    if offsets_m is None:
        return 0
    return int(np.count_nonzero(np.any(offsets_m != 0.0, axis=(1, 2))))


def _tracking(stats: RunStats, velocity: FloatArray) -> TrackingError:
    """Return the error of `velocity` (len(stats.t_ns), 3) against the reference at each tick."""
    ticks = np.asarray(stats.t_ns, dtype=np.int64)
    nu_ref = np.asarray(stats.nu_ref, dtype=np.float64).reshape(-1, 3)
    return TrackingError.of(tracking_error(ticks, velocity, ticks, nu_ref))


def period_jitter_p99_ms(tick_ns: list[int], nominal_s: float) -> float:
    """Return the 99th percentile of |period - nominal| over consecutive ticks (ms)."""
    if len(tick_ns) < 2:
        return 0.0
    periods = np.diff(np.asarray(tick_ns, dtype=np.int64)).astype(np.float64) / 1e6
    return float(np.percentile(np.abs(periods - nominal_s * 1e3), 99))
