"""Scenarios (layer 1): the arena, obstacles, target, grids and margins of a docking problem.

:mod:`hil.scenarios.scenario` loads and validates scenario TOML files (the packaged
``paper.toml`` and ``coarse.toml`` live beside it). Imports only :mod:`hil.core`.
"""

__all__: list[str] = []
