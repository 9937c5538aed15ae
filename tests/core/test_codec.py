import enum
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from hil.core.codec import CodecError, from_jsonable, to_jsonable


class Colour(enum.Enum):
    RED = "red"
    BLUE = "blue"


@dataclass(frozen=True, slots=True)
class Inner:
    xyz: tuple[float, float, float]
    colour: Colour = Colour.RED


@dataclass(frozen=True)
class Outer:
    name: str
    count: int
    inner: Inner
    inners: tuple[Inner, ...]
    maybe: tuple[float, float] | None
    path: Path | None
    flags: list[bool]
    extra: dict[str, Any]


def _round_trip(value: object) -> Any:
    return json.loads(json.dumps(to_jsonable(value)))


def test_nested_frozen_data_round_trips_exactly_through_json() -> None:
    value = Outer("o", 3, Inner((0.1, -1e-300, math.inf), Colour.BLUE),
                  (Inner((1.0, 2.0, 3.0)),), None, Path("/tmp/x"), [True, False],
                  {"k": [1, 2.5]})
    data = _round_trip(value)
    assert data["inner"]["colour"] == "blue"
    back = from_jsonable(Outer, data)
    assert back == value
    assert isinstance(back.inner.xyz, tuple)
    assert back.inner.xyz[2] == math.inf
    # NaN travels too (and is not equal to itself, so compared apart).
    nan = from_jsonable(Inner, _round_trip(Inner((math.nan, 0.0, 0.0))))
    assert math.isnan(nan.xyz[0])
    assert from_jsonable(tuple[Inner, int], _round_trip((Inner((1.0, 2.0, 3.0)), 4))) == (
        Inner((1.0, 2.0, 3.0)), 4)


@pytest.mark.parametrize(
    ("kind", "data", "needle"),
    [
        (Inner, {"xyz": [1.0, 2.0]}, "no tuple"),
        (Inner, {"xyz": [1.0, 2.0, "3"]}, "'3' is no float"),
        (Inner, {"xyz": [1.0, 2.0, 3.0], "colour": "green"}, "'green' is no Colour"),
        (Inner, {"xyz": [1.0, 2.0, 3.0], "size": 1}, "unknown fields \\['size'\\]"),
        (Inner, {}, "cannot build Inner"),
        (int, True, "True is no int"),
    ],
)
def test_what_does_not_fit_is_refused_by_name(kind: Any, data: Any, needle: str) -> None:
    with pytest.raises(CodecError, match=needle):
        from_jsonable(kind, data)
