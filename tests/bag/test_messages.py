"""Every stream encoded by hil decodes with rosbags and mcap_ros2 to the same values."""

from __future__ import annotations

import math
from typing import Any

import pytest
from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory

from hil.bag import topics
from hil.bag import typestore as ts
from hil.bag.decoding import to_record
from hil.bag.errors import RecordValueError
from hil.bag.lab_frame import DEFAULT_LAB_FRAME
from hil.bag.messages import Record, encode
from hil.core.records import Decision, Event, EventLevel, StateEstimate
from hil.core.samples import Frame, PoseSample, ThrusterCommand
from tests.bag.bag_streams import one_of_each
from tests.bag.reference_messages import FIXED_TYPES, reference_payloads


def assert_same(got: Record | None, want: Record) -> None:
    """Equal field by field; yaw through a quaternion is compared to 1e-12 rad."""
    assert got is not None
    if isinstance(want, PoseSample | StateEstimate):
        assert type(got) is type(want)
        assert math.isclose(got.yaw_rad, want.yaw_rad, abs_tol=1e-12)
        assert got == type(want)(**{**_fields(want), "yaw_rad": got.yaw_rad})
    else:
        assert got == want


def _fields(record: Any) -> dict[str, Any]:
    return {name: getattr(record, name) for name in record.__slots__}


IDENTITY = DEFAULT_LAB_FRAME.transform


@pytest.mark.parametrize("record", one_of_each(1_234_567_891, 3), ids=lambda r: type(r).__name__)
def test_rosbags_decodes_what_hil_encodes(record: Record) -> None:
    store = ts.typestore()
    pairs = encode(record)
    assert pairs
    for topic, payload in pairs:
        msgtype = topics.TOPIC_TYPES[topic]
        msg = store.deserialize_cdr(payload, msgtype)
        if topic != topics.THRUSTERS and isinstance(record, ThrusterCommand):
            continue  # the lab's per-thruster topics are checked below
        if topic == topics.POSE and isinstance(record, PoseSample):  # lab frame (identity)
            lab = record if record.frame is Frame.LAB_NED else IDENTITY.to_lab(record)
            assert_same(to_record(msgtype, msg), lab)
        elif msgtype in (topics.TWIST_TYPE, topics.WRENCH_TYPE):  # the lab's unstamped command
            assert to_record(msgtype, msg) is None
            stamped = dict(pairs)[topics.STREAM_TOPICS_BY_STREAM[topic]]
            assert payload[4:] == stamped[-48:]  # the same six doubles
        elif topic == topics.HIL_POSE and isinstance(record, PoseSample):  # the arena's
            arena = record if record.frame is Frame.ARENA else IDENTITY.to_arena(record)
            assert_same(to_record(msgtype, msg), arena)
        else:
            assert_same(to_record(msgtype, msg), record)
        # rosbags' own serializer gives the same bytes as hil's struct layouts.
        assert bytes(store.serialize_cdr(msg, msgtype)) == payload


@pytest.mark.parametrize(
    "record",
    [r for r in one_of_each(1_234_567_891, 3) if isinstance(r, FIXED_TYPES)],
    ids=lambda r: type(r).__name__,
)
def test_fixed_layouts_equal_the_independent_reference(record: Record) -> None:
    """The field table's encoding is what rosbags serializes from hand-built messages."""
    got = encode(record)
    want = reference_payloads(record)
    assert [t for t, _ in got] == [t for t, _ in want]
    for (topic, payload), (_, reference) in zip(got, want, strict=True):
        if topic in (topics.THRUSTER_PORT, topics.THRUSTER_STARBOARD):
            continue  # numpy's cos and sin: checked to within rounding below
        assert payload == reference, topic


def test_stamp_holds_the_sample_time() -> None:
    (lab, lab_payload), (topic, payload) = encode(PoseSample(3_000_000_007, 0.0, 0.0, 0.0))
    assert (lab, topic) == (topics.POSE, topics.HIL_POSE)
    for name, data, frame in ((lab, lab_payload, "world_ned"), (topic, payload, "arena")):
        msg: Any = ts.typestore().deserialize_cdr(data, topics.TOPIC_TYPES[name])
        assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (3, 7)
        assert msg.header.frame_id == frame


def test_lab_thruster_topics_follow_the_lab_convention() -> None:
    command = ThrusterCommand(5, 0.5, -0.25, 0.75, 1.25, -1.5)
    store = ts.typestore()
    out: dict[str, Any] = {
        t: store.deserialize_cdr(p, topics.TOPIC_TYPES[t]) for t, p in encode(command)
    }
    assert out[topics.THRUSTER_TUNNEL].force.x == 0.5
    port = out[topics.THRUSTER_PORT].force
    assert (port.x, port.y) == pytest.approx((-0.25 * math.cos(1.25), -0.25 * math.sin(1.25)))
    starboard = out[topics.THRUSTER_STARBOARD].force
    assert (starboard.x, starboard.y) == pytest.approx(
        (0.75 * math.cos(-1.5), 0.75 * math.sin(-1.5))
    )


@pytest.mark.parametrize("record", one_of_each(2_000_000_000, 1), ids=lambda r: type(r).__name__)
def test_mcap_ros2_decodes_what_hil_encodes(record: Record) -> None:
    """The independent decoder of mcap-ros2-support reads our schemas and payloads."""
    for topic, payload in encode(record):
        msgtype = topics.TOPIC_TYPES[topic]
        schema = Schema(
            id=1, name=msgtype, encoding="ros2msg", data=ts.schema_text(msgtype).encode()
        )
        decoder = DecoderFactory().decoder_for("cdr", schema)
        assert decoder is not None
        msg = decoder(payload)
        if topic == topics.DECISION:
            assert isinstance(record, Decision)
            assert (msg.x, msg.y, msg.psi) == record.state
            assert list(msg.safe_inputs) == [v for row in record.safe_inputs for v in row]
            assert list(msg.safe_input_indices) == list(record.safe_input_indices)
            assert msg.chosen_index == record.chosen_index
            assert msg.scenario_hash == record.scenario_hash
            assert msg.value == record.value
        elif topic == topics.IMU:
            assert msg.angular_velocity.z == record.yaw_rate_radps  # type: ignore[union-attr]
            assert msg.orientation_covariance[0] == -1.0
        elif topic == topics.EVENTS:
            assert isinstance(record, Event)
            assert (msg.level, msg.code, msg.text) == (int(record.level), record.code, record.text)
        elif topic == topics.OBSTACLES:
            assert len(msg.real) == len(record.obstacles)  # type: ignore[union-attr]
        elif topic == topics.ODOM:
            assert msg.child_frame_id == "body"
            assert msg.twist.twist.angular.z == record.yaw_rate_radps  # type: ignore[union-attr]


def test_unknown_record_type_is_refused() -> None:
    with pytest.raises(RecordValueError, match=r"cannot record 'str'"):
        encode("pose")  # type: ignore[arg-type]


def test_time_that_does_not_fit_a_stamp_is_refused() -> None:
    with pytest.raises(RecordValueError, match="does not fit a ROS stamp"):
        encode(PoseSample(2**31 * 1_000_000_000, 0.0, 0.0, 0.0))


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda: StateEstimate(0, math.nan, 0, 0, 0, 0, 0), "non-finite"),
        (lambda: StateEstimate(-1, 0, 0, 0, 0, 0, 0), "non-negative integer"),
        (
            lambda: Decision.from_arrays(0, [0, 0, math.nan], 0, 1.0, True, [], [], -1, 0, ""),
            "non-finite",
        ),
        (
            lambda: Decision.from_arrays(0, [0, 0, 0], 0, math.nan, True, [], [], -1, 0, ""),
            "finite or \\+inf",
        ),
        (
            lambda: Decision.from_arrays(0, [0, 0, 0], 0, 1.0, True, [[0.1, 0, 0]], [3], 5, 0, ""),
            "not among the safe inputs",
        ),
        (lambda: Event(0, 30, "x", "y"), "EventLevel"),  # type: ignore[arg-type]
    ],
)
def test_bad_values_are_refused_before_writing(build: Any, match: str) -> None:
    with pytest.raises(RecordValueError, match=match):
        build()


def test_event_level_survives() -> None:
    event = Event(1, EventLevel.FATAL, "stop", "thrusters failed")
    ((topic, payload),) = encode(event)
    msg = ts.typestore().deserialize_cdr(payload, topics.TOPIC_TYPES[topic])
    assert to_record(topics.TOPIC_TYPES[topic], msg) == event
