"""The HIL runtime: clocks, the control loop, re-synthesis, run summaries."""

from hil.runtime.clock import SimClock, WallClock

__all__ = ["SimClock", "WallClock"]
