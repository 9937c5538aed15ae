"""Settings of the control loop: its rate, decision period and fault thresholds."""

from __future__ import annotations

import math
from dataclasses import dataclass

from hil.core.clock import NS_PER_S

__all__ = ["NS_PER_S", "LoopConfig"]



@dataclass(frozen=True, slots=True)
class LoopConfig:
    """Timing and fault thresholds of the loop.

    Attributes:
        loop_hz: Rate of the low-level loop (Hz); 20 Hz as on the vessel.
        decision_period_s: Period of symbolic decisions, the abstraction's tau (s).
        resynthesis_period_s: Re-synthesize on this timer as well as on obstacle
            changes (s); None for changes only.
        pose_timeout_s: A pose older than this puts the loop on hold (s).
        dock_hold_s: Time to stay in the target before the run counts as docked (s).
        max_duration_s: The run stops with a timeout after this long (s).
        max_thruster_failures: Consecutive delivery failures before stopping.
        observer_settle_s: A first decision (start, or after a hold or a stop) waits
            until the observer has fused poses this long without a gap (s): its velocity
            estimate picks the reference in force, and the filter's start-up transient
            (up to 0.1 m/s in the first 0.3 s, measured on the simulated EKF) is larger
            than the half grid step the start budget allows.
        synthesis_threads: Kernel threads of a re-synthesis beside the loop: 1 leaves
            the other cores alone (a 2-core laptop, a campaign's processes); the vessel's
            4-core Pi can give it 3 (the verdict is the same: the game's solution does not
            depend on the thread count).
    """

    loop_hz: float = 20.0
    decision_period_s: float = 2.0
    resynthesis_period_s: float | None = 2.0
    pose_timeout_s: float = 0.5
    dock_hold_s: float = 4.0
    max_duration_s: float = 600.0
    max_thruster_failures: int = 20
    observer_settle_s: float = 1.0
    synthesis_threads: int = 1

    def __post_init__(self) -> None:
        if isinstance(self.synthesis_threads, bool) or not (
            isinstance(self.synthesis_threads, int) and self.synthesis_threads >= 1
        ):
            raise ValueError(
                f"loop config 'synthesis_threads' must be a whole number >= 1, "
                f"got {self.synthesis_threads!r}"
            )
        if not (math.isfinite(self.observer_settle_s) and self.observer_settle_s >= 0):
            raise ValueError(f"observer_settle_s must be >= 0, got {self.observer_settle_s!r}")
        for name in ("loop_hz", "decision_period_s", "pose_timeout_s", "max_duration_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"loop config {name!r} must be positive, got {value!r}")
        if self.dock_hold_s < 0:
            raise ValueError(f"loop config 'dock_hold_s' must be >= 0, got {self.dock_hold_s!r}")
        if self.resynthesis_period_s is not None and not self.resynthesis_period_s > 0:
            raise ValueError(
                "loop config 'resynthesis_period_s' must be positive or None, "
                f"got {self.resynthesis_period_s!r}"
            )

    @property
    def period_ns(self) -> int:
        """Loop period (ns)."""
        return round(NS_PER_S / self.loop_hz)
