"""Messages back into samples: the fast payload decoders agree with rosbags + to_record."""

from __future__ import annotations

import math
import struct

import pytest

from hil.bag import topics
from hil.bag import typestore as ts
from hil.bag.decoding import FAST_DECODERS, SAMPLE_TYPES, to_record
from hil.bag.messages import Record, encode
from hil.core.records import ForceCommand, StateEstimate
from hil.core.samples import (
    ImuSample,
    PoseSample,
    SampleError,
    ThrusterCommand,
    VelocityReference,
)

FIXED: list[Record] = [
    PoseSample(1_500_000_000, 1.25, -2.5, 3.0),
    ImuSample(2_000_000_001, 0.1, -0.2, 0.3),
    StateEstimate(3_000_000_000, 1.0, 2.0, -3.0, 0.1, -0.05, 0.2),
    VelocityReference(4_000_000_000, 0.1, 0.0, -0.01),
    ForceCommand(5_000_000_000, 10.0, -2.0, 0.5),
    ThrusterCommand(6_000_000_000, 0.5, -0.25, 1.0, 2.0, -1.0),
]


@pytest.mark.parametrize("record", FIXED, ids=lambda r: type(r).__name__)
def test_fast_decoder_equals_rosbags_and_to_record(record: Record) -> None:
    store = ts.jazzy_typestore()
    ts.register_hil_types(store)
    topic, payload = encode(record)[-1]  # thruster commands: the lossless /hil/thrusters
    msgtype = topics.TOPIC_TYPES[topic]
    assert msgtype in SAMPLE_TYPES
    slow = to_record(msgtype, store.deserialize_cdr(payload, msgtype))
    fast = FAST_DECODERS[msgtype](payload)
    assert fast == slow
    assert fast is not None
    assert fast.t_ns == record.t_ns


def test_fast_decoder_leaves_a_foreign_layout_to_rosbags() -> None:
    _, (_, payload) = encode(PoseSample(0, 1.0, 2.0, 0.5))  # the lab's pose, then /hil/pose
    big_endian = b"\x00\x00" + payload[2:]
    assert FAST_DECODERS[topics.POSE_TYPE](big_endian) is None
    assert FAST_DECODERS[topics.POSE_TYPE](payload[:-8]) is None


def test_a_value_a_sample_refuses_is_refused_on_both_paths() -> None:
    ((_, payload),) = encode(ImuSample(0, 0.0, 0.0, 0.0))
    bad = bytearray(payload)
    offset = len(bad) - 37 * 8 + 15 * 8  # angular_velocity.z among the 37 doubles
    bad[offset : offset + 8] = struct.pack("<d", math.nan)
    with pytest.raises(SampleError):
        FAST_DECODERS[topics.IMU_TYPE](bytes(bad))
    store = ts.jazzy_typestore()
    with pytest.raises(SampleError):
        to_record(topics.IMU_TYPE, store.deserialize_cdr(bytes(bad), topics.IMU_TYPE))


def test_types_without_a_record_give_none() -> None:
    assert to_record(topics.WRENCH_TYPE, object()) is None
