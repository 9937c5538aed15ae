"""A whole topic as numpy columns: one time vector and one array per field.

For analysis and plotting (tracking error over a run, Rerun's ``send_columns``)
a topic is more useful as arrays than as a stream of samples. Fixed-layout
payloads of equal length are decoded in one pass: the payloads are stacked into
an ``(N, L)`` byte matrix and the float64 block viewed in place. Payloads of
another layout (a foreign frame id of varying length, big-endian CDR) fall back
to per-message decoding, with the same result.
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hil.bag import topics
from hil.bag import typestore as ts
from hil.bag.errors import MessageDecodeError
from hil.bag.messages import Record
from hil.bag.storage import RawMessage
from hil.core.arrays import FloatArray
from hil.core.geometry import quaternion_yaws


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


@dataclass(frozen=True, slots=True)
class _Spec:
    """Where the fields of one message type sit among its float64 values."""

    n_values: int
    fields: tuple[tuple[str, int], ...]
    yaw_from: int | None = None  # index of the quaternion x when the type has a yaw
    child_frame: bool = False


_SPECS: dict[str, _Spec] = {
    topics.POSE_TYPE: _Spec(43, (("x_m", 0), ("y_m", 1)), yaw_from=3),
    topics.IMU_TYPE: _Spec(
        37, (("accel_x_mps2", 25), ("accel_y_mps2", 26), ("yaw_rate_radps", 15))
    ),
    topics.ODOM_TYPE: _Spec(
        85,
        (("x_m", 0), ("y_m", 1), ("surge_mps", 43), ("sway_mps", 44), ("yaw_rate_radps", 48)),
        yaw_from=3,
        child_frame=True,
    ),
    topics.TWIST_STAMPED_TYPE: _Spec(6, (("surge_mps", 0), ("sway_mps", 1), ("yaw_rate_radps", 5))),
    topics.WRENCH_STAMPED_TYPE: _Spec(6, (("surge_n", 0), ("sway_n", 1), ("yaw_nm", 5))),
    ts.THRUSTER_COMMANDS: _Spec(
        5,
        (
            ("tunnel", 0),
            ("port", 1),
            ("starboard", 2),
            ("port_angle_rad", 3),
            ("starboard_angle_rad", 4),
        ),
    ),
}

COLUMN_TYPES: frozenset[str] = frozenset(_SPECS)
"""Message types :func:`to_columns` reads."""


def _field_names(spec: _Spec) -> tuple[str, ...]:
    names = tuple(name for name, _ in spec.fields)
    return (*names[:2], "yaw_rad", *names[2:]) if spec.yaw_from is not None else names


def _values_offset(first: bytes, spec: _Spec) -> int | None:
    """Byte offset of the float64 block in `first`, or None if not little-endian CDR."""
    if len(first) < 16 or first[1] != 1:
        return None
    offset = 16 + int.from_bytes(first[12:16], "little")
    if spec.child_frame:
        offset += (-(offset - 4)) % 4
        offset += 4 + int.from_bytes(first[offset : offset + 4], "little")
    offset += (-(offset - 4)) % 8
    return offset if len(first) == offset + 8 * spec.n_values else None


def _frame_id(data: bytes) -> str:
    length = int.from_bytes(data[12:16], "little")
    return data[16 : 16 + length - 1].decode("utf-8", "replace")


def _bulk(
    raws: Sequence[RawMessage], spec: _Spec
) -> tuple[NDArray[np.int64], dict[str, FloatArray]] | None:
    """Decode equal-layout payloads (same length, header and frame ids) in one pass."""
    first = raws[0].data
    offset = _values_offset(first, spec)
    if offset is None:
        return None
    size, head, frames = len(first), first[:4], first[12:offset]
    if not all(
        len(r.data) == size and r.data[12:offset] == frames and r.data[:4] == head for r in raws
    ):
        return None
    matrix = np.frombuffer(b"".join(r.data for r in raws), dtype=np.uint8).reshape(len(raws), size)
    stamp = np.ascontiguousarray(matrix[:, 4:12]).view("<u4")
    t_ns = stamp[:, 0].view("<i4").astype(np.int64) * 1_000_000_000 + stamp[:, 1]
    values = np.ascontiguousarray(matrix[:, offset:]).view("<f8")
    fields = {name: values[:, i].copy() for name, i in spec.fields}
    if spec.yaw_from is not None:
        x, y, z, w = (values[:, spec.yaw_from + k] for k in range(4))
        fields["yaw_rad"] = quaternion_yaws(x, y, z, w)
    return t_ns, fields


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
    spec = _SPECS.get(msgtype)
    if spec is None:
        raise MessageDecodeError(
            f"topic {topic!r} of type {msgtype!r} has no columns; "
            f"types with columns: {sorted(COLUMN_TYPES)!r}"
        )
    names = _field_names(spec)
    if not raws:
        return Columns(topic, np.zeros(0, np.int64), {n: np.zeros(0) for n in names})
    bulk = _bulk(raws, spec)
    if bulk is not None:  # every payload carries the first one's frame ids
        t_ns, fields = bulk
        if all(np.isfinite(v).all() for v in fields.values()):
            return Columns(topic, t_ns, {n: fields[n] for n in names}, _frame_id(raws[0].data))
    frame_ids = {_frame_id(r.data) for r in raws if len(r.data) >= 16}
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
