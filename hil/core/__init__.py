"""Core (layer 0): what every other layer shares, importing nothing of hil.

- :mod:`hil.core.geometry`: angle wrapping, rotations, shapes (numba kernels);
- :mod:`hil.core.jit`: ``njit`` with a numba cache keyed by the package sources;
- :mod:`hil.core.samples`: sensor and actuator samples (pose, IMU, thrusters, layouts);
- :mod:`hil.core.records`: what the stack records besides samples (decisions, events);
- :mod:`hil.core.tracking`: the velocity-tracking error (join, units, sign);
- :mod:`hil.core.transient`: the transient budget (bounds on the deviation from the
  exact arc per period class and time bin, velocity-error envelopes, EKF error);
- :mod:`hil.core.clock`: simulated and wall clocks;
- :mod:`hil.core.config`: TOML tables into frozen dataclasses, errors naming the key.

Import the modules by their full path: this package re-exports nothing, so that
importing a light module (samples) does not compile kernels (geometry).
"""

__all__: list[str] = []
