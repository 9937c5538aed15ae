"""A whole topic as numpy columns: one time vector and one array per field.

For analysis and plotting (tracking error over a run, Rerun's ``send_columns``)
a topic is more useful as arrays than as a stream of samples. Fixed-layout
payloads of equal length are decoded in one pass: the payloads are stacked into
an ``(N, L)`` byte matrix and the float64 block viewed in place, its fields where the
field table (:mod:`hil.bag.field_table`) puts them. Payloads of another layout (a
foreign frame id of varying length, big-endian CDR) fall back to per-message
decoding, with the same result.
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hil.bag import cdr
from hil.bag import field_table as ft
from hil.bag.errors import MessageDecodeError
from hil.bag.messages import Record
from hil.bag.storage import RawMessage
from hil.core.arrays import FloatArray


@dataclass(frozen=True, slots=True)
class Columns:
    """A topic's messages as columns.

    Attributes:
        topic: Topic name.
        t_ns: Header stamps (ns), shape (N,), int64, in log-time order.
        fields: Field name (the sample attribute, e.g. ``"x_m"``) -> values, shape (N,).
        frame_id: Header frame id shared by every message ("" when there are none).
    """

    topic: str
    t_ns: NDArray[np.int64]
    fields: dict[str, FloatArray]
    frame_id: str = ""

    def stack(self, *names: str) -> FloatArray:
        """Return the named fields side by side, shape (N, len(names)), time-major."""
        return np.column_stack([self.fields[name] for name in names])


COLUMN_TYPES: frozenset[str] = ft.STAMPED_TYPES
"""Message types :func:`to_columns` reads."""


def _bulk(
    raws: Sequence[RawMessage], layout: ft.FixedLayout
) -> tuple[NDArray[np.int64], dict[str, FloatArray]] | None:
    """Decode equal-layout payloads (same length, header and frame ids) in one pass."""
    first = raws[0].data
    off = ft.offsets(layout)
    head = cdr.parse_header(first, off.child_frame)
    if head is None or len(first) != head.values_offset + 8 * off.n_values:
        return None
    size, offset = len(first), head.values_offset
    encapsulation, frames = first[: cdr.DATA_START], first[cdr.FRAME_OFFSET : offset]
    if not all(
        len(r.data) == size
        and r.data[cdr.FRAME_OFFSET : offset] == frames
        and r.data[: cdr.DATA_START] == encapsulation
        for r in raws
    ):
        return None
    matrix = np.frombuffer(b"".join(r.data for r in raws), dtype=np.uint8).reshape(len(raws), size)
    t_ns = cdr.stamps_ns(matrix[:, cdr.STAMP_OFFSET : cdr.FRAME_OFFSET])
    values = np.ascontiguousarray(matrix[:, offset:]).view("<f8")
    return t_ns, ft.from_values(layout, values)


def to_columns(
    topic: str,
    msgtype: str,
    raws: Sequence[RawMessage],
    to_record: Callable[[RawMessage], Record | None],
) -> Columns:
    """Decode the messages of one topic into columns.

    Args:
        topic: Topic name.
        msgtype: Its message type (one of :data:`COLUMN_TYPES`).
        raws: Its raw messages in log-time order.
        to_record: Per-message decoder, used when the payloads are not uniform.

    Returns:
        The columns; field names are the sample attributes.

    Raises:
        MessageDecodeError: The type has no columns, or a message does not decode.
    """
    layout = ft.LAYOUTS.get(msgtype)
    if layout is None or msgtype not in COLUMN_TYPES:
        raise MessageDecodeError(
            f"topic {topic!r} of type {msgtype!r} has no columns; "
            f"types with columns: {sorted(COLUMN_TYPES)!r}"
        )
    names = layout.names
    if not raws:
        return Columns(topic, np.zeros(0, np.int64), {n: np.zeros(0) for n in names})
    bulk = _bulk(raws, layout)
    if bulk is not None:  # every payload carries the first one's frame ids
        t_ns, fields = bulk
        if all(np.isfinite(v).all() for v in fields.values()):
            return Columns(topic, t_ns, fields, cdr.frame_id(raws[0].data))
    frame_ids = {cdr.frame_id(r.data) for r in raws if len(r.data) >= cdr.FRAME_OFFSET + 4}
    frame_id = next(iter(frame_ids), "")
    if len(frame_ids) > 1:
        raise MessageDecodeError(
            f"topic {topic!r} mixes frames {sorted(frame_ids)!r}; read it as records instead"
        )
    # Uneven layouts or a bad value: decode one by one (which names the bad message).
    records = [r for r in (to_record(raw) for raw in raws) if r is not None]
    get = operator.attrgetter("t_ns", *names)
    rows = [get(r) for r in records]
    t_ns = np.array([row[0] for row in rows], dtype=np.int64)
    values = np.array([row[1:] for row in rows], dtype=np.float64).reshape(len(rows), len(names))
    return Columns(topic, t_ns, {n: values[:, i] for i, n in enumerate(names)}, frame_id)
