"""Borrowed views (hil.core.borrow): the owner's memory, read and written through slices."""

from __future__ import annotations

import numpy as np
import pytest
from numba.core.errors import TypingError

from hil.core.borrow import borrowed
from hil.core.jit import njit


@njit
def _row_sums_through_slices(a: np.ndarray, lo: int, hi: int) -> np.ndarray:
    view = borrowed(a)
    out = np.zeros(view.shape[0], dtype=np.uint64)
    for r in range(view.shape[0]):
        row = view[r, lo:hi]
        for v in row:
            out[r] += v
    return out


@njit
def _double_band(a: np.ndarray, lo: int, hi: int) -> None:
    a = borrowed(a)
    for r in range(a.shape[0]):
        band = a[r, lo:hi]
        for i in range(band.shape[0]):
            band[i] *= np.uint64(2)


@njit
def _fill(scratch: np.ndarray, value: int) -> None:
    for i in range(scratch.shape[0]):
        scratch[i] = value


@njit
def _allocated_scratch_total(n: int, repeats: int) -> int:
    total = 0
    for r in range(repeats):
        scratch = np.empty(n, dtype=np.int64)
        _fill(borrowed(scratch), r)  # the owner is held by this statement
        total += int(scratch.sum())
    return total


def test_slices_of_a_borrowed_view_read_the_owners_words() -> None:
    a = np.arange(6 * 40, dtype=np.uint64).reshape(6, 40)
    np.testing.assert_array_equal(_row_sums_through_slices(a, 3, 31), a[:, 3:31].sum(axis=1))


def test_writes_through_a_borrowed_view_reach_the_owner() -> None:
    a = np.arange(4 * 10, dtype=np.uint64).reshape(4, 10)
    expected = a.copy()
    expected[:, 2:7] *= 2
    _double_band(a, 2, 7)
    np.testing.assert_array_equal(a, expected)


def test_a_borrowed_allocation_handed_to_a_call_holds_its_values() -> None:
    assert _allocated_scratch_total(1000, 50) == 1000 * sum(range(50))


@njit
def _borrow_a_number(x: int) -> int:
    return borrowed(x)


def test_only_arrays_are_borrowed() -> None:
    with pytest.raises(TypingError):
        _borrow_a_number(3)
