"""The bag format (layer 5): rosbag2 MCAP recording, reading, recovery, loading a run.

May import :mod:`hil.core` only (samples and records are what it writes); the log
backend, the runtime's recorder use, replay and views build on it.

Names are loaded on first use (PEP 562), so that importing one light module such
as :mod:`hil.core.records` does not pull in rosbags, mcap and the reader.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from hil.bag.columns import COLUMN_TYPES, Columns
    from hil.bag.errors import (
        BagError,
        BagFormatError,
        BagNotFoundError,
        MessageDecodeError,
        NotAHilRunError,
        RecorderClosedError,
        RecorderError,
        RecordValueError,
        RecoveryError,
        ReplayError,
        SchemaError,
        UnsupportedBagError,
    )
    from hil.bag.messages import Record, encode, to_record
    from hil.bag.reader import BagInfo, BagReader, SkippedMessage, TopicInfo, describe
    from hil.bag.recorder import Recorder, RecorderConfig, RecordSink, RunInfo
    from hil.bag.recover import RecoveryReport, inspect_recovery, recover
    from hil.bag.storage import RawMessage

_WHERE: dict[str, str] = {
    "COLUMN_TYPES": "columns",
    "Columns": "columns",
    "BagError": "errors",
    "BagFormatError": "errors",
    "BagNotFoundError": "errors",
    "MessageDecodeError": "errors",
    "NotAHilRunError": "errors",
    "RecorderClosedError": "errors",
    "RecorderError": "errors",
    "RecordValueError": "errors",
    "RecoveryError": "errors",
    "ReplayError": "errors",
    "SchemaError": "errors",
    "UnsupportedBagError": "errors",
    "Record": "messages",
    "encode": "messages",
    "to_record": "messages",
    "BagInfo": "reader",
    "BagReader": "reader",
    "SkippedMessage": "reader",
    "TopicInfo": "reader",
    "describe": "reader",
    "Recorder": "recorder",
    "RecorderConfig": "recorder",
    "RecordSink": "recorder",
    "RunInfo": "recorder",
    "RecoveryReport": "recover",
    "inspect_recovery": "recover",
    "recover": "recover",
    "RawMessage": "storage",
}

__all__ = [
    "COLUMN_TYPES",
    "BagError",
    "BagFormatError",
    "BagInfo",
    "BagNotFoundError",
    "BagReader",
    "Columns",
    "MessageDecodeError",
    "NotAHilRunError",
    "RawMessage",
    "Record",
    "RecordSink",
    "RecordValueError",
    "Recorder",
    "RecorderClosedError",
    "RecorderConfig",
    "RecorderError",
    "RecoveryError",
    "RecoveryReport",
    "ReplayError",
    "RunInfo",
    "SchemaError",
    "SkippedMessage",
    "TopicInfo",
    "UnsupportedBagError",
    "describe",
    "encode",
    "inspect_recovery",
    "recover",
    "to_record",
]


def __getattr__(name: str) -> Any:
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'hil.bag' has no attribute {name!r}")
    return getattr(importlib.import_module(f"hil.bag.{module}"), name)
