"""Recording (rosbag2 MCAP), reading, recovery, replay, regression checks and Rerun export.

Names are loaded on first use (PEP 562), so that importing one light module such
as :mod:`hil.replay.records` does not pull in rosbags, mcap and the reader.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from hil.replay.columns import COLUMN_TYPES, Columns
    from hil.replay.errors import (
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
    from hil.replay.messages import Record, encode, to_record
    from hil.replay.reader import BagInfo, BagReader, SkippedMessage, TopicInfo, describe
    from hil.replay.recorder import Recorder, RecorderConfig, RecordSink, RunInfo
    from hil.replay.records import Decision, Event, EventLevel, ForceCommand, StateEstimate
    from hil.replay.recover import RecoveryReport, inspect_recovery, recover
    from hil.replay.storage import RawMessage

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
    "Decision": "records",
    "Event": "records",
    "EventLevel": "records",
    "ForceCommand": "records",
    "StateEstimate": "records",
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
    "Decision",
    "Event",
    "EventLevel",
    "ForceCommand",
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
    "StateEstimate",
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
        raise AttributeError(f"module 'hil.replay' has no attribute {name!r}")
    return getattr(importlib.import_module(f"hil.replay.{module}"), name)
