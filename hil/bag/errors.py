"""Exceptions of the recorder and the bag reader.

Every message names the offending path or value (with ``!r``) and what is wrong
with it, so that a command can print ``str(err)`` as its one-line error.
"""

from __future__ import annotations

from hil.core.records import RecordValueError

__all__ = [
    "BagError",
    "BagFormatError",
    "BagNotFoundError",
    "FrameError",
    "MessageDecodeError",
    "NotAHilRunError",
    "OldLogFormatError",
    "RecordValueError",
    "RecorderClosedError",
    "RecorderError",
    "RecoveryError",
    "ReplayError",
    "SchemaError",
    "UnsupportedBagError",
]


class ReplayError(Exception):
    """Base class of every error raised by :mod:`hil.bag`."""


class BagError(ReplayError, ValueError):
    """A log that cannot be read as asked."""


class BagNotFoundError(BagError, FileNotFoundError):
    """The log path does not exist."""


class BagFormatError(BagError):
    """The path exists but is not a readable rosbag2 directory or MCAP file."""


class UnsupportedBagError(BagFormatError):
    """A well-formed log hil cannot decode (non-ROS 2 profile, unknown encoding)."""


class SchemaError(BagError):
    """A message definition in the log cannot be parsed or conflicts with a known one."""


class MessageDecodeError(BagError):
    """One message's payload cannot be decoded with its type."""


class OldLogFormatError(BagFormatError):
    """A hil log of an older layout this code cannot judge (its message says why)."""


class NotAHilRunError(BagError):
    """A valid log that holds none of the topics hil records."""


class FrameError(BagError):
    """A recorded stream in a frame hil cannot use (poses not in the arena, mixed frames)."""


class RecorderError(ReplayError, RuntimeError):
    """The recorder cannot accept or write a message."""


class RecorderClosedError(RecorderError):
    """The recorder is used before open() or after close()."""


class RecoveryError(ReplayError):
    """A truncated bag cannot be recovered."""
