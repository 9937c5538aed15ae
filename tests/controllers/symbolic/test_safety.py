"""The safety game's set (safety, safety_kernel) against a dense re-computation, and its lookup.

The reference iterates S_p = (V0_p and Pre0(S_p)) or OR over u in N(p) of (V1_u and Pre1(S_u))
with numpy on boolean arrays straight from the tables (no bit packing, no bands), from
"every state" down to the fixed point; the kernel must give the same set bit for bit.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from numpy.typing import NDArray

from hil.controllers.symbolic import Controller, SymbolicProblem, Synthesizer
from hil.controllers.symbolic.safety import solve_safe_set
from hil.core.shapes import Rect
from tests.controllers.symbolic import tiny

BoolArray = NDArray[np.bool_]


def _unpack(words: NDArray[np.uint64], ny: int) -> BoolArray:
    """Bits (..., nw) -> bools (..., ny)."""
    bits = np.unpackbits(words.view(np.uint8).reshape(*words.shape, 8), axis=-1, bitorder="little")
    return bits.reshape(*words.shape[:-1], -1)[..., :ny].astype(bool)


def _dense_safe(c: Controller) -> BoolArray:
    """Return S as bools (m, nx, ny, npsi) by plain iteration on the tables."""
    t, g = c.tables, c.grid
    nx, ny, npsi = g.shape
    m = t.n_inputs
    cells = np.transpose(c.viable_words, (0, 1, 4, 2, 3))  # (3, m, nx, npsi, nw)
    viable = _unpack(np.ascontiguousarray(cells), ny)  # (3, m, nx, npsi, ny)
    V = [np.transpose(viable[cls], (0, 1, 3, 2)) for cls in (0, 1)]  # (m, nx, ny, npsi)
    nbr = [c.lattice.neighbours[p, : c.lattice.n_neighbours[p]] for p in range(m)]

    def pre(cls: int, u: int, S: BoolArray) -> BoolArray:
        out = np.zeros((nx, ny, npsi), dtype=bool)
        for k in range(npsi):
            ox0, ox1, oy0, oy1 = (int(v) for v in t.succ[cls, k, u])
            h0, h1 = (int(v) for v in t.heading[cls, u])
            ok = np.ones((nx, ny), dtype=bool)
            for ox, oy, oh in itertools.product(
                range(ox0, ox1 + 1), range(oy0, oy1 + 1), range(h0, h1 + 1)
            ):
                layer = S[u, :, :, (k + oh) % npsi]
                shifted = np.zeros((nx, ny), dtype=bool)
                xs = slice(max(0, -ox), min(nx, nx - ox))
                ys = slice(max(0, -oy), min(ny, ny - oy))
                xd = slice(max(0, ox), min(nx, nx + ox))
                yd = slice(max(0, oy), min(ny, ny + oy))
                shifted[xs, ys] = layer[xd, yd]
                ok &= shifted
            out[:, :, k] = ok
        return out

    S = np.ones((m, nx, ny, npsi), dtype=bool)
    while True:
        A = np.stack([V[0][u] & pre(0, u, S) for u in range(m)])
        B = np.stack([V[1][u] & pre(1, u, S) for u in range(m)])
        new = np.stack(
            [A[p] | np.any(B[nbr[p]], axis=0) if len(nbr[p]) else A[p] for p in range(m)]
        )
        new &= S
        if np.array_equal(new, S):
            return S
        S = new


def _kernel_safe(c: Controller) -> BoolArray:
    words = c.safe_words
    assert words is not None
    px, _, pw = (int(v) for v in c.pads)
    nx, ny, _ = c.grid.shape
    nw = (ny + 63) // 64
    inner = words[:, :, pw : pw + nw, px : px + nx].transpose(0, 1, 3, 2)
    bits = _unpack(np.ascontiguousarray(inner), ny)
    return np.transpose(bits, (0, 2, 3, 1))  # (m, npsi, nx, ny) -> (m, nx, ny, npsi)


def _solve(problem: SymbolicProblem, threads: int = 1) -> Controller:
    tables, _ = problem.tables(use_cache=False)
    return Synthesizer(tables, threads=threads, memo=False, use_cache=False).solve_problem(problem)


@pytest.mark.parametrize("layout", ["one obstacle", "two obstacles"])
def test_the_kernel_gives_the_dense_fixed_point(layout: str) -> None:
    # The zero budget: on the tiny grid's 0.1-m cells a realistic one leaves no state
    # that can stay (every box too wide), which would test nothing.
    second = (Rect(-0.5, -0.3, 0.4, 1.0),) if layout != "one obstacle" else ()
    obstacles = (tiny.OBSTACLE, *second)
    problem = tiny.problem(tiny.zero_budget(), obstacles=obstacles)
    c = _solve(problem)
    dense = _dense_safe(c)
    np.testing.assert_array_equal(_kernel_safe(c), dense)
    assert dense.any()
    assert not dense.all()


def test_threads_give_the_same_set() -> None:
    problem = tiny.problem(
        tiny.zero_budget(), obstacles=(Rect(-0.4, -0.2, -0.5, 0.3), tiny.OBSTACLE)
    )
    one = _solve(problem)
    lat = one.lattice
    t = one.tables
    two = solve_safe_set(one.viable_words, one.pads, t.succ, t.heading, lat.neighbours,
                         lat.n_neighbours, threads=2)  # fmt: skip
    assert one.safe_words is not None
    np.testing.assert_array_equal(two.bits, one.safe_words)


def test_a_synthesizer_reusing_its_working_arrays_gives_fresh_solves_sets() -> None:
    # The safety solve runs on the reach solve's working arrays, which the next solve of
    # the same synthesizer reuses: each layout's set must be the one a fresh solve finds.
    first = tiny.problem(tiny.zero_budget())
    second = tiny.problem(
        tiny.zero_budget(), obstacles=(Rect(-0.4, -0.2, -0.5, 0.3), tiny.OBSTACLE)
    )
    tables, _ = first.tables(use_cache=False)
    synthesizer = Synthesizer(tables, memo=False, use_cache=False)
    for problem in (first, second, first):
        c = synthesizer.solve_problem(problem)
        lat = c.lattice
        fresh = solve_safe_set(c.viable_words, c.pads, tables.succ, tables.heading,
                               lat.neighbours, lat.n_neighbours)  # fmt: skip
        assert c.safe_words is not None
        np.testing.assert_array_equal(c.safe_words, fresh.bits)
        np.testing.assert_array_equal(_kernel_safe(c), _dense_safe(c))


def test_staying_inputs_lead_into_the_set_and_exist_exactly_there() -> None:
    c = _solve(tiny.problem(tiny.zero_budget()))
    safe = _dense_safe(c)
    t = c.tables
    nx, ny, npsi = c.grid.shape
    rng = np.random.default_rng(5)
    seen_staying = 0
    for _ in range(400):
        p = int(rng.integers(t.n_inputs))
        cell = (int(rng.integers(nx)), int(rng.integers(ny)), int(rng.integers(npsi)))
        staying = c.staying_input_indices_at(cell, p)
        assert (staying.size > 0) == bool(safe[(p, *cell)])
        i, j, k = cell
        for u in staying:
            cls = 0 if u == p else 1
            ox0, ox1, oy0, oy1 = t.succ[cls, k, u]
            h0, h1 = t.heading[cls, u]
            for ox, oy, oh in itertools.product(
                range(ox0, ox1 + 1), range(oy0, oy1 + 1), range(h0, h1 + 1)
            ):
                assert safe[u, i + ox, j + oy, (k + oh) % npsi]
        seen_staying += int(staying.size > 0)
    assert seen_staying > 20


def test_a_losing_state_in_the_safety_set_is_answered_with_staying_inputs() -> None:
    c = _solve(tiny.problem(tiny.zero_budget()))
    safe = _dense_safe(c)
    rest = c.rest_index
    values = c.layer_values(rest)
    candidates = np.argwhere(safe[rest] & (values < 0))
    assert len(candidates), "the tiny problem has safe states that cannot dock"
    i, j, k = (int(v) for v in candidates[0])
    answer = c.decide_at((i, j, k), rest)
    assert answer.value == -1
    assert answer.staying
    assert answer.inputs.size > 0
    wi, wj, wk = (int(v) for v in np.argwhere(values > 0)[0])
    winning = (wi, wj, wk)
    docking = c.decide_at(winning, rest)
    assert docking.value > 0
    assert not docking.staying
    np.testing.assert_array_equal(docking.inputs, c.safe_input_indices_at(winning, rest))
