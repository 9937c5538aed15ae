"""The simulated world (layer 4): plant, sensor models and the compiled closed loop.

:mod:`hil.sim.plant` steps thrusters and hull together, :mod:`hil.sim.sensors` models
motion capture and the IMU, :mod:`hil.sim.closed_loop` runs sensors, the low level
(:mod:`hil.controllers.low_level`) and the plant in one compiled loop for benchmarks
and budgets; :mod:`hil.sim.transient` measures on it the scenarios' ``[transient]``
table. May import :mod:`hil.core`,
:mod:`hil.model`, :mod:`hil.scenarios` and :mod:`hil.controllers`; the adapters'
simulated backend builds on it.
"""

from hil.sim.errors import ClosedLoopConfigError

__all__ = ["ClosedLoopConfigError"]
