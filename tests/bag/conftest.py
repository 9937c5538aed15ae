"""Fixtures for the recorder and reader tests."""

from __future__ import annotations

import pytest

from hil.bag.messages import Record
from tests.bag.bag_streams import one_of_each


@pytest.fixture
def records() -> list[Record]:
    """Three rounds of every stream, 50 ms apart, starting at 1 s."""
    out: list[Record] = []
    for i in range(3):
        out.extend(one_of_each(1_000_000_000 + 50_000_000 * i, i))
    return out
