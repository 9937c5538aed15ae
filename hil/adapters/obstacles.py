"""An obstacle source for a fixed layout (the scenario's, on the vessel without a feed)."""

from __future__ import annotations

from hil.core.samples import ObstacleLayout


class StaticObstacleSource:
    """Always reports the same layout."""

    def __init__(self, layout: ObstacleLayout) -> None:
        self._layout = layout

    def latest(self) -> ObstacleLayout:
        """Return the fixed layout."""
        return self._layout
