"""Replay (layer 9): recorded runs re-run through the current code, and their verdicts.

:mod:`hil.replay.replayer` replays one log through the checks, each in its own module:
:mod:`~hil.replay.decisions`, :mod:`~hil.replay.tracking_checks` (tracking),
:mod:`~hil.replay.intervals` (contract),
:mod:`~hil.replay.stack_rerun` (the stack re-run) and :mod:`~hil.replay.resim` (closed loop),
with the thresholds of :mod:`~hil.replay.options` and the controllers of
:mod:`~hil.replay.controllers`; :mod:`hil.replay.regression` judges the differences,
:mod:`hil.replay.pytest_plugin` turns a folder of bags into test cases,
:mod:`hil.replay.truth` judges a run on a true trajectory recorded outside hil. May import every
layer below (runs, runtime, adapters, bag, sim, controllers, model, scenarios, core);
views and commands build on it.
"""

__all__: list[str] = []
