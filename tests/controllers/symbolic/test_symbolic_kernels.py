"""The bit kernels against plain-numpy twins, and the value lookups against each other."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.symbolic import Controller, SymbolicProblem
from hil.controllers.symbolic.frontier_kernel import init_layers, shifted, successor_run
from hil.controllers.symbolic.kernels import layer_values, pack_rows, state_value, state_values
from hil.controllers.symbolic.viable import erode_free
from tests.controllers.symbolic import tiny

U64Array = NDArray[np.uint64]


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
        got = _bits(np.array([shifted(lo, hi, np.uint64(s))], dtype=np.uint64))
        np.testing.assert_array_equal(got, both[s : s + 64], err_msg=f"s={s}")


def test_erode_free_erodes_like_numpy() -> None:
    rng = np.random.default_rng(0)
    nx, ny, px, pw = 3, 100, 2, 2
    free = rng.random((nx, ny)) < 0.8
    nw = (ny + 63) // 64
    layers = 5
    f0 = np.zeros((nw + 2 * pw, nx + 2 * px), dtype=np.uint64)
    f0[pw : pw + nw, px : px + nx] = pack_rows(free).T
    f = np.zeros((layers, nw + 2 * pw, nx + 2 * px), dtype=np.uint64)
    erode_free(f0, f)
    for h in range(layers):
        got = _bits(np.ascontiguousarray(f[h, pw : pw + nw, px : px + nx].T))
        padded = np.concatenate([free, np.zeros((nx, h), dtype=bool)], axis=1)
        expected = np.ones_like(free)
        for d in range(h + 1):
            expected &= padded[:, d : d + ny]
        np.testing.assert_array_equal(got[:, :ny], expected, err_msg=f"h={h}")
    assert not f[:, :, :px].any()  # rows outside the grid stay empty
    assert not f[:, :pw].any()


def test_successor_run_matches_numpy() -> None:
    """successor_run over W (m, rows x, rows k, words): runs of n cells in all k rows."""
    rng = np.random.default_rng(5)
    m, n_x, n_k, nw, pw = 2, 4, 6, 2, 2
    W = rng.integers(0, 2**64, size=(m, n_x, n_k, nw + 2 * pw), dtype=np.uint64)
    W |= rng.integers(0, 2**64, size=W.shape, dtype=np.uint64)  # denser: runs survive
    cells = _bits(W)  # (m, n_x, n_k, 64 (nw + 2 pw)), cell 0 at bit 64 pw
    for _ in range(200):
        u, x = int(rng.integers(m)), int(rng.integers(n_x))
        kp0 = int(rng.integers(n_k - 2))
        kp1 = kp0 + int(rng.integers(3))
        wp = pw + int(rng.integers(nw))
        oy0 = int(rng.integers(-6, 7))
        n = int(rng.integers(1, 9))
        got = _bits(np.array([successor_run(W, u, x, kp0, kp1, wp, oy0, n)], dtype=np.uint64))
        rows: NDArray[np.bool_] = np.asarray(cells[u, x, kp0 : kp1 + 1].all(axis=0))
        base = 64 * wp + oy0
        expected = np.array([rows[base + b : base + b + n].all() for b in range(64)])
        np.testing.assert_array_equal(got, expected, err_msg=f"{(u, x, kp0, kp1, wp, oy0, n)}")


def test_init_layers_copies_the_goal_into_every_layer_and_wrap() -> None:
    rng = np.random.default_rng(2)
    m, nx, npsi, nw, px, ph, pw = 3, 4, 5, 2, 2, 2, 2
    goal = rng.integers(0, 2**64, size=(nx, npsi, nw), dtype=np.uint64)
    goal[1, 2] = 0  # a row without goal is not marked
    W = np.zeros((m, nx + 2 * px, npsi + 2 * ph, nw + 2 * pw), dtype=np.uint64)
    n_rw = (nx * npsi + 63) // 64
    chmask = np.zeros((m, n_rw), dtype=np.uint64)
    assert init_layers(goal, W, px, ph, pw, chmask) == nx * npsi - 1
    for p in range(m):
        np.testing.assert_array_equal(W[p, px : px + nx, ph : ph + npsi, pw : pw + nw], goal)
        for kp in range(npsi + 2 * ph):  # padding heading rows hold the row they wrap to
            k = (kp - ph) % npsi
            np.testing.assert_array_equal(W[p, px : px + nx, kp, pw : pw + nw], goal[:, k])
        marked = _bits(chmask[p])[: nx * npsi]
        np.testing.assert_array_equal(marked, (goal != 0).any(axis=-1).reshape(-1))
    assert not W[:, :px].any()
    assert not W[:, :, :, :pw].any()


def test_viable_words_are_the_free_tubes(problem: SymbolicProblem, controller: Controller) -> None:
    t = controller.tables
    g = t.grid
    free = tiny.flat_free(problem, t)
    cells = np.transpose(controller._viable, (0, 1, 4, 2, 3))  # (3, m, nx, npsi, nw)
    viable = _bits(np.ascontiguousarray(cells))[..., : g.ny]  # (3, m, nx, npsi, ny)
    rng = np.random.default_rng(2)
    checked = 0
    for c in range(3):
        for k in rng.choice(g.npsi, 4, replace=False):
            for u in range(0, t.n_inputs, 2):
                for i in range(g.nx):
                    for j in range(0, g.ny, 3):
                        want = tiny.tube_free(t, free, c, (i, j, int(k)), u)
                        assert viable[c, u, i, k, j] == want, (c, i, j, k, u)
                        checked += want
    assert checked > 1000


def test_value_lookups_agree(controller: Controller) -> None:
    W, planes, pads = controller._W, controller._planes, controller._pads
    g = controller.grid
    nw = planes.shape[3]  # (m, nx, npsi, nw, n_planes)
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
