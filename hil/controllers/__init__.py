"""Controllers (layer 2): the stack's math, free of any world, clock or log.

- :mod:`hil.controllers.symbolic`: the upper level (grid, abstraction, synthesis,
  safe inputs, the paper's cost J);
- :mod:`hil.controllers.low_level`: the one low-level tick the runtime and the compiled
  closed loop both run: :mod:`~hil.controllers.pid` (velocity PID) and allocation
  (:mod:`~hil.controllers.allocation`, its kernels in
  :mod:`~hil.controllers.allocation_kernels`, the force envelope in
  :mod:`~hil.controllers.envelope`);
- the EKF observer: :mod:`~hil.controllers.observer` (its face),
  :mod:`~hil.controllers.observer_kernels`, :mod:`~hil.controllers.observer_math`,
  :mod:`~hil.controllers.observer_arrays`, :mod:`~hil.controllers.observer_ring`.

May import :mod:`hil.model`, :mod:`hil.scenarios` and :mod:`hil.core`; the simulator,
adapters and runtime build on it.
"""

__all__: list[str] = []
