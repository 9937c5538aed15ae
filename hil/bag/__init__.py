"""The bag format (layer 5): rosbag2 MCAP recording, reading, recovery, loading a run.

The fixed-layout messages' one field table is :mod:`~hil.bag.field_table`, their CDR
bytes (alignment, strings, stamps) :mod:`~hil.bag.cdr`; every codec below reads both.
Writing: :mod:`~hil.bag.messages` (records as ROS 2 messages), :mod:`~hil.bag.columnar`
(bulk encoding), :mod:`~hil.bag.lab_frame` (the lab's pose frame),
:mod:`~hil.bag.mcap_writer`, :mod:`~hil.bag.recorder`, :mod:`~hil.bag.metadata`,
:mod:`~hil.bag.run_info` (what produced a run). Reading:
:mod:`~hil.bag.storage`, :mod:`~hil.bag.reader`, :mod:`~hil.bag.decoding` (messages
back into records), :mod:`~hil.bag.columns` (a topic as arrays),
:mod:`~hil.bag.recover`, and :mod:`~hil.bag.run_data`, the one loader of a recorded
run that the log backend, replay and views all use.

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
    from hil.bag.decoding import to_record
    from hil.bag.errors import (
        BagError,
        BagFormatError,
        BagNotFoundError,
        FrameError,
        MessageDecodeError,
        NotAHilRunError,
        OldLogFormatError,
        RecorderClosedError,
        RecorderError,
        RecordValueError,
        RecoveryError,
        ReplayError,
        SchemaError,
        UnsupportedBagError,
    )
    from hil.bag.messages import Record, encode
    from hil.bag.reader import BagInfo, BagReader, SkippedMessage, TopicInfo, describe
    from hil.bag.recorder import Recorder, RecorderConfig, RecordSink
    from hil.bag.recover import RecoveryReport, inspect_recovery, recover
    from hil.bag.repairs import Repair, RepairKind
    from hil.bag.run_data import RunData, Series, load_run
    from hil.bag.run_info import RunInfo
    from hil.bag.storage import RawMessage

_WHERE: dict[str, str] = {
    "COLUMN_TYPES": "columns",
    "Columns": "columns",
    "BagError": "errors",
    "BagFormatError": "errors",
    "BagNotFoundError": "errors",
    "FrameError": "errors",
    "MessageDecodeError": "errors",
    "NotAHilRunError": "errors",
    "OldLogFormatError": "errors",
    "RecorderClosedError": "errors",
    "RecorderError": "errors",
    "RecordValueError": "errors",
    "RecoveryError": "errors",
    "ReplayError": "errors",
    "SchemaError": "errors",
    "UnsupportedBagError": "errors",
    "Record": "messages",
    "encode": "messages",
    "to_record": "decoding",
    "BagInfo": "reader",
    "BagReader": "reader",
    "SkippedMessage": "reader",
    "TopicInfo": "reader",
    "describe": "reader",
    "Recorder": "recorder",
    "RecorderConfig": "recorder",
    "RecordSink": "recorder",
    "RunInfo": "run_info",
    "Repair": "repairs",
    "RepairKind": "repairs",
    "RunData": "run_data",
    "Series": "run_data",
    "load_run": "run_data",
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
    "FrameError",
    "MessageDecodeError",
    "NotAHilRunError",
    "OldLogFormatError",
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
    "Repair",
    "RepairKind",
    "ReplayError",
    "RunData",
    "RunInfo",
    "SchemaError",
    "Series",
    "SkippedMessage",
    "TopicInfo",
    "UnsupportedBagError",
    "describe",
    "encode",
    "inspect_recovery",
    "load_run",
    "recover",
    "to_record",
]


def __getattr__(name: str) -> Any:
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'hil.bag' has no attribute {name!r}")
    return getattr(importlib.import_module(f"hil.bag.{module}"), name)
