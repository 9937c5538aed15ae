"""The lab's pose frame as the recorder writes it: the transform and the frame id."""

from __future__ import annotations

from dataclasses import dataclass, field

from hil.bag import topics
from hil.bag.errors import RecordValueError
from hil.core.arena_frame import ArenaTransform


@dataclass(frozen=True, slots=True)
class LabFrame:
    """The lab's pose frame: how hil's arena poses map back to what the lab's topic holds.

    Attributes:
        transform: Lab world and mocap body to the arena and the vessel's body origin
            (the vessel config's ``[ros.transform]``; identity in simulation by default).
        frame_id: Frame id of the lab's poses (``[ros] pose_frame_id``, ``world_ned``).
    """

    transform: ArenaTransform = field(default_factory=ArenaTransform)
    frame_id: str = topics.LAB_FRAME

    def __post_init__(self) -> None:
        if not self.frame_id or "\x00" in self.frame_id:
            raise RecordValueError(f"lab pose frame id {self.frame_id!r} is empty or has a NUL")


DEFAULT_LAB_FRAME = LabFrame()
"""Identity transform, ``world_ned``: what simulation records without a vessel config."""
