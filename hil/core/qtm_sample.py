"""One QTM 6D frame of the vessel's rigid body, as received: what the bag keeps of QTM.

The qtm pose backend (:mod:`hil.adapters.qtm`) makes an arena pose of each frame;
this record keeps the frame itself (QTM's time and frame number, millimetres and the
rotation matrix, QTM's drop fields and hil's drop and loss counters), so a replay
can check the recorded pose against it and a view can show what QTM sent. Recorded
as ``hil_msgs/Qtm6D`` on ``/hil/qtm/6d`` (:mod:`hil.bag.topics`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hil.core.records import RecordValueError

ROTATION_LEN = 9
"""Floats in a QTM rotation matrix."""


@dataclass(frozen=True, slots=True)
class QtmSample:
    """One QTM 6D frame of one rigid body, as received.

    Unlike the samples, it keeps NaN: a lost body is what QTM sent.

    Attributes:
        t_ns: QTM's timestamp mapped onto the run clock (ns): the pose's stamp.
        timestamp_us: QTM's own timestamp (us, QTM's clock).
        frame_number: QTM's frame number.
        body_index: The body's index among QTM's 6D bodies.
        body: The body's name.
        position_mm: (x, y, z) in QTM's axes (mm), NaN when lost.
        rotation: The rotation matrix, 9 floats in QTM's column order, NaN when lost.
        residual_mm: The 6D residual (mm); NaN when QTM does not stream it.
        drop_rate: The 6D component's drop rate field, as QTM sends it.
        out_of_sync_rate: The 6D component's out-of-sync rate field, as QTM sends it.
        drops: Frames the feed counted dropped so far (frame-number gaps).
        lost: Frames so far with the body lost or without a heading.
    """

    t_ns: int
    timestamp_us: int
    frame_number: int
    body_index: int
    body: str
    position_mm: tuple[float, float, float]
    rotation: tuple[float, ...]
    residual_mm: float = math.nan
    drop_rate: int = 0
    out_of_sync_rate: int = 0
    drops: int = 0
    lost: int = 0

    def __post_init__(self) -> None:
        if len(self.position_mm) != 3 or len(self.rotation) != ROTATION_LEN:
            raise RecordValueError(
                f"QTM sample needs 3 position and {ROTATION_LEN} rotation values, got "
                f"{len(self.position_mm)} and {len(self.rotation)}"
            )
        if min(self.t_ns, self.frame_number, self.drops, self.lost) < 0:
            raise RecordValueError(f"QTM sample has a negative time or count: {self!r}")

    @property
    def seen(self) -> bool:
        """Whether QTM saw the body (a finite position and rotation)."""
        return all(math.isfinite(v) for v in (*self.position_mm, *self.rotation))
