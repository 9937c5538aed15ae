"""The runtime (layer 7): the control loop, the stack's protocols and its assembly.

:mod:`hil.runtime.loop` runs observer, symbolic decisions, low level and recording at a
fixed rate against a :class:`~hil.runtime.loop.World` of adapters, with the settings
of :mod:`hil.runtime.settings` and counting into :mod:`hil.runtime.stats`;
:mod:`hil.runtime.protocols` declares the components it calls, :mod:`hil.runtime.assembly`
wires the real ones, :mod:`hil.runtime.resynthesis` re-synthesizes beside the loop.
May import adapters, bag, sim, controllers, model, scenarios and core; the runs build
on it.
"""

from hil.runtime.events import EventCode
from hil.runtime.loop import Runtime, World
from hil.runtime.mode import Mode
from hil.runtime.resynthesis import ResynthesisMode, Resynthesizer, SynthesisResult
from hil.runtime.settings import LoopConfig
from hil.runtime.stats import RunStats

__all__ = [
    "EventCode",
    "LoopConfig",
    "Mode",
    "ResynthesisMode",
    "Resynthesizer",
    "RunStats",
    "Runtime",
    "SynthesisResult",
    "World",
]
