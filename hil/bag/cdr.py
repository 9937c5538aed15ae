"""Little-endian CDR in one place: encapsulation, alignment, strings and header stamps.

Every codec of hil's fixed-layout messages (:mod:`hil.bag.field_table`) builds and
parses payloads with these. A payload is the 4-byte encapsulation header (``00 01 00 00``,
CDR little endian) and the data; alignment counts from the start of the data (byte 4 of
the payload). A stamped message's data starts with ``std_msgs/Header``: the stamp (int32
seconds, uint32 nanoseconds) and the frame id (uint32 length with its NUL, the bytes,
the NUL); odometry adds the child frame id (4-aligned); the float64 block that follows is
8-aligned. A header stamp holds a sample time in ns >= 0 that fits int32 seconds.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from hil.bag.errors import RecordValueError
from hil.core.clock import NS_PER_S, stamp_fields

ENCAPSULATION = b"\x00\x01\x00\x00"
"""CDR, little endian, no options."""

DATA_START = len(ENCAPSULATION)
"""Byte offset of the data in a payload; alignment counts from here."""

STAMP_OFFSET = DATA_START
"""Byte offset of a header's stamp (int32 sec, uint32 nanosec) in a payload."""

FRAME_OFFSET = STAMP_OFFSET + 8
"""Byte offset of a header's frame id length (uint32) in a payload."""

MAX_T_NS = 2**31 * NS_PER_S
"""The first time (ns) a ROS stamp (int32 seconds) cannot hold."""

_HEAD = struct.Struct("<iII")  # sec, nanosec, frame_id length (with NUL)
_LENGTH = struct.Struct("<I")


def pad(offset: int, align: int) -> int:
    """Return the zero bytes that align `offset` (bytes from the data start) to `align`."""
    return (-offset) % align


def string(text: str) -> bytes:
    """Return a CDR string: uint32 length (with the NUL), the UTF-8 bytes and the NUL."""
    data = text.encode() + b"\x00"
    return _LENGTH.pack(len(data)) + data


def stamp(t_ns: int) -> tuple[int, int]:
    """Return (sec, nanosec) of a time in ns.

    Raises:
        RecordValueError: The time is negative or past int32 seconds.
    """
    if t_ns < 0 or t_ns >= MAX_T_NS:
        raise RecordValueError(f"time {t_ns!r} ns does not fit a ROS stamp (int32 seconds >= 0)")
    return stamp_fields(t_ns)


def check_stamps(t_ns: NDArray[np.int64]) -> None:
    """Refuse times (N,) in ns that do not fit a ROS stamp, naming the first (as :func:`stamp`)."""
    bad = (t_ns < 0) | (t_ns >= MAX_T_NS)
    if bad.any():
        stamp(int(t_ns[bad][0]))


def stamp_bytes(t_ns: NDArray[np.int64]) -> NDArray[np.uint8]:
    """Return the stamps of times (N,) in ns as their CDR bytes, shape (N, 8)."""
    sec, nsec = np.divmod(t_ns, NS_PER_S)
    out = np.empty((len(t_ns), 2), dtype="<u4")
    out[:, 0] = sec.astype("<i4").view("<u4")
    out[:, 1] = nsec
    return out.view(np.uint8)


def stamps_ns(stamps: NDArray[np.uint8]) -> NDArray[np.int64]:
    """Return the times in ns of CDR stamps, shape (N, 8) bytes -> (N,) int64."""
    pairs = np.ascontiguousarray(stamps).view("<u4")
    out: NDArray[np.int64] = pairs[:, 0].view("<i4").astype(np.int64) * NS_PER_S + pairs[:, 1]
    return out


def prefix(frame_id: str | None, child_frame_id: str | None = None) -> bytes:
    """Return the bytes of a payload before its float64 block, the stamp left zero.

    Args:
        frame_id: The header's frame id; None for a message without a header (the
            float64 block starts the data).
        child_frame_id: The child frame id after the header (odometry), or None.
    """
    if frame_id is None:
        return ENCAPSULATION
    data = b"\x00" * 8 + string(frame_id)
    if child_frame_id is not None:
        data += b"\x00" * pad(len(data), 4) + string(child_frame_id)
    return ENCAPSULATION + data + b"\x00" * pad(len(data), 8)


class Header(NamedTuple):
    """What :func:`parse_header` reads of a stamped payload."""

    t_ns: int
    """The stamp (ns)."""
    frame_id: str
    """The header's frame id (undecodable bytes replaced)."""
    values_offset: int
    """Byte offset of the float64 block after the header (and child frame id)."""


def parse_header(data: bytes, child_frame: bool = False) -> Header | None:
    """Read the header of a little-endian CDR payload; None when it is not one.

    Args:
        data: The payload.
        child_frame: A child frame id follows the header (odometry).
    """
    if len(data) < FRAME_OFFSET + 4 or data[1] != 1:  # encapsulation 0x0001: CDR little endian
        return None
    sec, nsec, length = _HEAD.unpack_from(data, STAMP_OFFSET)
    offset = FRAME_OFFSET + 4 + length
    frame = data[FRAME_OFFSET + 4 : offset - 1].decode("utf-8", "replace")
    if child_frame:
        offset += pad(offset - DATA_START, 4)
        if offset + 4 > len(data):
            return None
        (child_length,) = _LENGTH.unpack_from(data, offset)
        offset += 4 + child_length
    offset += pad(offset - DATA_START, 8)
    return Header(sec * NS_PER_S + nsec, frame, offset)


def frame_id(data: bytes) -> str:
    """Return the header's frame id of a stamped payload (undecodable bytes replaced)."""
    length = int.from_bytes(data[FRAME_OFFSET : FRAME_OFFSET + 4], "little")
    return data[FRAME_OFFSET + 4 : FRAME_OFFSET + 4 + length - 1].decode("utf-8", "replace")
