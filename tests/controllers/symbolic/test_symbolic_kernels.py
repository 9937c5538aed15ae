"""The bit kernels against plain-numpy twins, and the value lookups against each other."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.symbolic import Controller, SymbolicProblem
from hil.controllers.symbolic.kernels import layer_values, pack_rows, state_value, state_values
from hil.controllers.symbolic.sweep import _shifted, erode_free
from tests.controllers.symbolic import tiny

U64Array = NDArray[np.uint64]


def _bits(words: U64Array) -> NDArray[np.bool_]:
    """Unpack uint64 words (..., nw) to bools (..., 64 nw), bit j of word w at 64 w + j."""
    out = (words[..., :, None] >> np.arange(64, dtype=np.uint64)) & np.uint64(1)
    return out.reshape(*words.shape[:-1], -1).astype(bool)


@pytest.mark.parametrize("ny", [1, 5, 63, 64, 70, 130])
def test_pack_rows_matches_numpy(ny: int) -> None:
    mask = np.random.default_rng(ny).random((3, ny)) < 0.6
    packed = pack_rows(mask)
    assert packed.shape == (3, (ny + 63) // 64)
    np.testing.assert_array_equal(_bits(packed)[:, :ny], mask)
    assert not _bits(packed)[:, ny:].any()


def test_shifted_reads_across_the_word_boundary() -> None:
    rng = np.random.default_rng(1)
    lo, hi = (np.uint64(v) for v in rng.integers(0, 2**63, 2, dtype=np.uint64))
    both = np.concatenate(
        [_bits(np.array([lo], dtype=np.uint64)), _bits(np.array([hi], dtype=np.uint64))]
    )
    for s in (0, 1, 17, 63):
        got = _bits(np.array([_shifted(lo, hi, np.uint64(s))], dtype=np.uint64))
        np.testing.assert_array_equal(got, both[s : s + 64], err_msg=f"s={s}")


def test_erode_free_matches_numpy() -> None:
    rng = np.random.default_rng(0)
    rows, ny, layers = 4, 150, 70  # runs longer than a word
    free = rng.random((rows, ny)) < 0.97
    free[0] = True
    words = pack_rows(free)
    out = np.zeros((layers, rows, words.shape[1]), dtype=np.uint64)
    erode_free(words, out)
    for h in range(layers):
        padded = np.concatenate([free, np.zeros((rows, h), dtype=bool)], axis=1)
        expected = np.ones_like(free)
        for d in range(h + 1):
            expected &= padded[:, d : d + ny]
        np.testing.assert_array_equal(_bits(out[h])[:, :ny], expected, err_msg=f"h={h}")
        assert not _bits(out[h])[:, ny:].any()
    assert _bits(out[layers - 1])[0, : ny - layers + 1].all()


def test_viable_words_are_the_free_tubes(problem: SymbolicProblem, controller: Controller) -> None:
    t = controller.tables
    g = t.grid
    free = tiny.flat_free(problem, t)
    viable = _bits(controller._viable)[..., : g.ny]  # (3, nx, npsi, m, ny)
    rng = np.random.default_rng(2)
    checked = 0
    for c in range(3):
        for k in rng.choice(g.npsi, 4, replace=False):
            for u in range(0, t.n_inputs, 2):
                for i in range(g.nx):
                    for j in range(0, g.ny, 3):
                        want = tiny.tube_free(t, free, c, (i, j, int(k)), u)
                        assert viable[c, i, k, u, j] == want, (c, i, j, k, u)
                        checked += want
    assert checked > 1000


def test_value_lookups_agree(controller: Controller) -> None:
    W, planes, pads = controller._W, controller._planes, controller._pads
    g = controller.grid
    nw = planes.shape[3]
    i, j, k = (a.ravel().astype(np.int64) for a in np.indices(g.shape))
    seen_levels = set()
    for p in range(0, controller.tables.n_inputs, 3):
        layer = layer_values(W, planes, pads, p, g.ny)
        np.testing.assert_array_equal(layer, controller.layer_values(p))
        np.testing.assert_array_equal(state_values(W, planes, pads, p, i, j, k), layer.ravel())
        for n in range(0, len(i), 37):
            assert state_value(W, planes, pads, p, i[n], j[n], k[n]) == layer.ravel()[n]
        seen_levels |= set(np.unique(layer).tolist())
        # Off the grid, and rows past ny in the last word: losing. Headings wrap.
        for jj in range(g.ny, 64 * nw):
            assert state_value(W, planes, pads, p, 3, jj, 0) == -1
        for ii, jj in ((-1, 0), (g.nx, 0), (0, -1), (g.nx + 5, 3)):
            assert state_value(W, planes, pads, p, ii, jj, 0) == -1
        for kk in (-1, -g.npsi, g.npsi, 2 * g.npsi + 3):
            want = layer[4, 7, kk % g.npsi]
            assert state_value(W, planes, pads, p, 4, 7, kk) == want
    assert {-1, 0, 1, 2} <= seen_levels
