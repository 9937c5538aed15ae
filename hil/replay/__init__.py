"""Replay (layer 9): recorded runs re-run through the current code, and their verdicts.

:mod:`hil.replay.replayer` re-runs decisions and the stack on a recorded run,
:mod:`hil.replay.regression` judges the differences, :mod:`hil.replay.pytest_plugin`
turns a folder of bags into test cases. May import every layer below (runs, runtime,
adapters, bag, sim, controllers, model, scenarios, core); views and commands build on it.
"""

__all__: list[str] = []
