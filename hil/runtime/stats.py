"""What the control loop counts during a run, for the run's summary."""

from __future__ import annotations

from dataclasses import dataclass, field

from hil.core.arrays import FloatArray
from hil.runtime.events import EventCode

__all__ = ["RunStats"]



@dataclass
class RunStats:
    """Counters and time series the loop keeps for the run's summary.

    Series are time-major lists, one row per tick under control: `t_ns`,
    `eta_hat` (3,), `nu_hat` (3,), `nu_ref` (3,); `tick_wall_ns` holds the clock
    time at which every tick started (for the period jitter). `tube_exits`,
    `successor_misses` and `value_not_decreasing` count the runtime monitor's
    violations (:mod:`hil.runtime.monitor`), the worst sizes in metres beside them;
    `obstacle_stale_stops` the stops for an obstacle report too old to decide on;
    `brake_s` how long the vessel braked to rest after a stop (s; None: no braking);
    `late_intervals` the decisions later than tau + late after the previous one, the
    worst by how much (s);
    with obstacles that move, `report_age_relied_s` the oldest a relied-on report was
    when a fresher one took over and `report_age_solved_s` the largest report age a
    controller in force was solved for (s; 0: none);
    `estimate_inconsistent_ns` the stamp of the pose at which the EKF's innovations
    broke its noise model (None: consistent; :mod:`hil.controllers.consistency`);
    `staying_decisions` the decisions taken on the safety controller (docking not
    winning) and `docking_lost` the episodes of them; `layout_waits` the waits at rest
    for a layout that wins (obstacles move, the state outside both sets).
    """

    start_ns: int = 0
    end_ns: int = 0
    overruns: int = 0
    tick_wall_ns: list[int] = field(default_factory=list)
    decisions: int = 0
    resyntheses: int = 0
    early_controllers: int = 0
    synthesis_seconds: list[float] = field(default_factory=list)
    failed_syntheses: int = 0
    rejected_samples: int = 0
    pose_losses: int = 0
    obstacle_stale_stops: int = 0
    brake_s: float | None = None
    late_intervals: int = 0
    worst_late_s: float = 0.0
    report_age_relied_s: float = 0.0
    report_age_solved_s: float = 0.0
    estimate_inconsistent_ns: int | None = None
    thruster_failures: int = 0
    not_winning_decisions: int = 0
    staying_decisions: int = 0
    docking_lost: int = 0
    layout_waits: int = 0
    tube_exits: int = 0
    successor_misses: int = 0
    value_not_decreasing: int = 0
    worst_tube_exit_m: float = 0.0
    worst_successor_miss_m: float = 0.0
    target_reached_ns: int | None = None
    docked_ns: int | None = None
    end_reason: str = ""
    aborted: bool = False
    t_ns: list[int] = field(default_factory=list)
    eta_hat: list[FloatArray] = field(default_factory=list)
    nu_hat: list[FloatArray] = field(default_factory=list)
    nu_ref: list[FloatArray] = field(default_factory=list)

    def count_violation(self, code: EventCode, size: float) -> None:
        """Count one broken promise of a decision (the runtime monitor's `code`, `size` in m)."""
        if code is EventCode.TUBE_EXIT:
            self.tube_exits += 1
            self.worst_tube_exit_m = max(self.worst_tube_exit_m, size)
        elif code is EventCode.SUCCESSOR_MISS:
            self.successor_misses += 1
            self.worst_successor_miss_m = max(self.worst_successor_miss_m, size)
        else:
            self.value_not_decreasing += 1
