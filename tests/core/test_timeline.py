"""The value in force at a time: the newest start at or before it."""

from __future__ import annotations

import numpy as np

from hil.core.timeline import in_force


def test_a_value_holds_from_its_own_stamp_until_the_next() -> None:
    starts = np.array([10, 20, 20, 35], dtype=np.int64)
    times = np.array([5, 10, 19, 20, 34, 35, 1000], dtype=np.int64)
    # Before the first start: -1. On a stamp: that value. Two at one stamp: the later row.
    np.testing.assert_array_equal(in_force(starts, times), [-1, 0, 0, 2, 2, 3, 3])


def test_no_starts_leave_nothing_in_force() -> None:
    np.testing.assert_array_equal(in_force(np.array([], dtype=np.int64), [1, 2]), [-1, -1])
    assert in_force([1, 2], np.array([], dtype=np.int64)).shape == (0,)
