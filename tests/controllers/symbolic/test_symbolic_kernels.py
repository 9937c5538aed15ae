"""The bit kernels against plain-numpy twins."""

from __future__ import annotations

import numpy as np
import pytest

from hil.controllers.symbolic.kernels import pack_rows
from hil.controllers.symbolic.sweep import _shifted, init_bits


def _bits(words: np.ndarray) -> np.ndarray:
    """Unpack uint64 words (..., nw) to bools (..., 64 nw), bit j of word w at 64 w + j."""
    out = (words[..., :, None] >> np.arange(64, dtype=np.uint64)) & np.uint64(1)
    return out.reshape(*words.shape[:-1], -1).astype(bool)


@pytest.mark.parametrize("ny", [5, 64, 70, 130])
def test_pack_rows_matches_numpy(ny: int) -> None:
    mask = np.random.default_rng(ny).random((3, ny)) < 0.6
    np.testing.assert_array_equal(_bits(pack_rows(mask))[:, :ny], mask)
    assert not _bits(pack_rows(mask))[:, ny:].any()


def test_shifted_reads_across_the_word_boundary() -> None:
    rng = np.random.default_rng(1)
    lo, hi = (np.uint64(v) for v in rng.integers(0, 2**63, 2, dtype=np.uint64))
    both = np.concatenate(
        [_bits(np.array([lo], dtype=np.uint64)), _bits(np.array([hi], dtype=np.uint64))]
    )
    for s in (0, 1, 17, 63):
        got = _bits(np.array([_shifted(lo, hi, np.uint64(s))], dtype=np.uint64))
        np.testing.assert_array_equal(got, both[s : s + 64], err_msg=f"s={s}")


def test_init_bits_erodes_like_numpy() -> None:
    rng = np.random.default_rng(0)
    nx, ny, npsi, px, pw = 3, 100, 4, 2, 2
    goal = rng.random((nx, ny)) < 0.9
    free = rng.random((nx, ny)) < 0.8
    nw = (ny + 63) // 64
    layers = 5
    e = np.zeros((layers, nx + 2 * px, npsi + 2, nw + 2 * pw), dtype=np.uint64)
    f = np.zeros((layers, nx + 2 * px, nw + 2 * pw), dtype=np.uint64)
    init_bits(pack_rows(goal), pack_rows(free), e, f, px, pw)
    for h in range(layers):
        for mask, got in (
            (goal, _bits(e[h, px : px + nx, 1, pw : pw + nw])),
            (free, _bits(f[h, px : px + nx, pw : pw + nw])),
        ):
            padded = np.concatenate([mask, np.zeros((nx, h), dtype=bool)], axis=1)
            expected = np.ones_like(mask)
            for d in range(h + 1):
                expected &= padded[:, d : d + ny]
            np.testing.assert_array_equal(got[:, :ny], expected, err_msg=f"h={h}")
    assert not e[:, :px].any()  # rows outside the grid stay empty: never winning
    assert not f[:, :, :pw].any()
