"""The HIL runtime: clocks, the control loop, re-synthesis, runs and their summaries.

`hil.runtime.sim_run` (a docking run in simulation), `hil.runtime.vessel_run`
(the stack on the vessel over ROS 2) and `hil.runtime.campaign` (Monte Carlo)
build on the loop; import them directly.
"""

from hil.runtime.clock import SimClock, WallClock
from hil.runtime.events import EventCode
from hil.runtime.loop import LoopConfig, Mode, RunStats, Runtime, World
from hil.runtime.resynthesis import ResynthesisMode, Resynthesizer, SynthesisResult
from hil.runtime.summary import RunSummary, TrackingError

__all__ = [
    "EventCode",
    "LoopConfig",
    "Mode",
    "ResynthesisMode",
    "Resynthesizer",
    "RunStats",
    "RunSummary",
    "Runtime",
    "SimClock",
    "SynthesisResult",
    "TrackingError",
    "WallClock",
    "World",
]
