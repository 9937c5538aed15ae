"""The solved-controller store: reads instead of solving, distrusts damaged files, LRU budget."""

from __future__ import annotations

import hashlib
import multiprocessing
import os
import struct
from collections import OrderedDict
from pathlib import Path

import numpy as np
import pytest

from hil.controllers.symbolic import Controller, SymbolicProblem, Synthesizer, Tables
from hil.controllers.symbolic import store as store_module
from hil.controllers.symbolic import synthesis as synthesis_module
from hil.controllers.symbolic.store import (
    BUDGET_ENV,
    DEFAULT_BUDGET_MB,
    ControllerStore,
    SolvedLayout,
    budget_bytes,
)


@pytest.fixture
def cache_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("HIL_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv(BUDGET_ENV, raising=False)
    return tmp_path


def _no_kernel(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the fixed point ran")

    # Every solve, whichever kernel, goes through Synthesizer.stages.
    monkeypatch.setattr(synthesis_module.Synthesizer, "stages", refuse)


def _solve(tables: Tables, problem: SymbolicProblem) -> Controller:
    synthesizer = Synthesizer(tables, memo=False)
    controller = synthesizer.solve_problem(problem)
    synthesizer.wait_stored()
    return controller


def _files(cache_dir: Path) -> list[Path]:
    return sorted((cache_dir / "controllers").glob("*.ctl"))


def _assert_same(a: Controller, b: Controller) -> None:
    np.testing.assert_array_equal(a.winning_words, b.winning_words)
    np.testing.assert_array_equal(a.value_planes, b.value_planes)
    np.testing.assert_array_equal(a.viable_words, b.viable_words)
    np.testing.assert_array_equal(a.values, b.values)
    assert a.stats.levels == b.stats.levels
    assert a.stats.winning_cells == b.stats.winning_cells


def test_a_second_solve_reads_the_first_from_disk(
    cache_dir: Path, problem: SymbolicProblem, tables: Tables, controller: Controller,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    first = _solve(tables, problem)
    assert not first.stats.loaded
    [path] = _files(cache_dir)
    _assert_same(first, controller)
    _no_kernel(monkeypatch)
    again = Synthesizer(tables, memo=False).solve_problem(problem)
    assert again.stats.loaded
    _assert_same(again, first)
    for p in range(tables.n_inputs):
        np.testing.assert_array_equal(again.layer_values(p), first.layer_values(p))
    i, j, k = (int(v) for v in np.argwhere(first.values > 0)[0])
    cell = (i, j, k)
    np.testing.assert_array_equal(
        again.safe_input_indices_at(cell), first.safe_input_indices_at(cell)
    )
    # Another layout is another file: it is solved (here: the kernel is gone).
    moved = problem.with_obstacles((problem.obstacles[0].translate(-0.3, 0.0),))
    with pytest.raises(AssertionError, match="fixed point ran"):
        Synthesizer(tables, memo=False).solve_problem(moved)
    assert _files(cache_dir) == [path]


def test_the_synthesizer_counts_where_each_controller_came_from(
    cache_dir: Path, problem: SymbolicProblem, tables: Tables, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(synthesis_module, "_MEMO", OrderedDict())  # no other test's solves
    synthesizer = Synthesizer(tables)
    synthesizer.solve_problem(problem)
    synthesizer.wait_stored()
    synthesizer.solve_problem(problem)  # the process's memo
    s = synthesizer.sources
    assert (s.solved, s.store, s.memory) == (1, 0, 1)
    fresh = Synthesizer(tables, memo=False)
    fresh.solve_problem(problem)
    assert (fresh.sources.solved, fresh.sources.store, fresh.sources.memory) == (0, 1, 0)
    assert fresh.sources.describe() == "0 solved, 1 from the store"
    before = s.copy()
    moved = problem.with_obstacles((problem.obstacles[0].translate(-0.3, 0.0),))
    synthesizer.solve_problem(moved)
    since = synthesizer.sources.minus(before)
    assert (since.solved, since.store, since.memory, since.total()) == (1, 0, 0, 1)


def _damaged(data: bytes, how: str) -> bytes:
    if how == "truncated":
        return data[: len(data) // 2]
    if how == "empty":
        return b""
    flipped = bytearray(data)
    position = {"payload": len(data) // 2, "header": 20, "checksum": len(data) - 1}[how]
    flipped[position] ^= 0x10
    return bytes(flipped)


@pytest.mark.parametrize("how", ["truncated", "empty", "payload", "header", "checksum"])
def test_a_damaged_file_is_re_solved_and_rewritten(
    cache_dir: Path, problem: SymbolicProblem, tables: Tables, controller: Controller, how: str
) -> None:
    _solve(tables, problem)
    [path] = _files(cache_dir)
    good = path.read_bytes()
    damaged = _damaged(good, how)
    path.write_bytes(damaged)
    again = _solve(tables, problem)
    assert not again.stats.loaded  # solved, not trusted
    _assert_same(again, controller)
    assert path.read_bytes() != damaged  # rewritten
    reread = _solve(tables, problem)
    assert reread.stats.loaded
    _assert_same(reread, controller)


def test_a_file_of_another_format_is_ignored(
    cache_dir: Path, problem: SymbolicProblem, tables: Tables, controller: Controller,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    _solve(tables, problem)
    [path] = _files(cache_dir)
    data = bytearray(path.read_bytes())
    # The same bytes under a future format number, with a valid checksum.
    struct.pack_into("<H", data, 6, store_module.FORMAT_VERSION + 1)
    body = bytes(data[:-32])
    path.write_bytes(body + hashlib.blake2b(body, digest_size=32).digest())
    assert not _solve(tables, problem).stats.loaded
    # A new format names its files by another key: old files are never looked up.
    monkeypatch.setattr(store_module, "FORMAT_VERSION", store_module.FORMAT_VERSION + 1)
    assert not _solve(tables, problem).stats.loaded
    assert len(_files(cache_dir)) == 2


def test_the_solver_sources_are_part_of_the_key(
    problem: SymbolicProblem, tables: Tables, monkeypatch: pytest.MonkeyPatch
) -> None:
    masks = (problem.inflated_obstacle_mask(),)
    before = store_module.solve_key(tables.key, masks)
    monkeypatch.setattr(store_module, "solver_digest", lambda: "another solver")
    assert store_module.solve_key(tables.key, masks) != before


def test_no_cache_writes_and_reads_nothing(
    cache_dir: Path, problem: SymbolicProblem, tables: Tables, controller: Controller,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    synthesizer = Synthesizer(tables, memo=False, use_cache=False)
    synthesizer.solve_problem(problem)
    synthesizer.wait_stored()
    assert not (cache_dir / "controllers").exists()
    _solve(tables, problem)
    assert _files(cache_dir)
    _no_kernel(monkeypatch)  # a stored file exists, but no-cache solves
    with pytest.raises(AssertionError, match="fixed point ran"):
        Synthesizer(tables, memo=False, use_cache=False).solve_problem(problem)
    monkeypatch.setenv(BUDGET_ENV, "0")  # a zero budget turns the store off too
    with pytest.raises(AssertionError, match="fixed point ran"):
        Synthesizer(tables, memo=False).solve_problem(problem)


def test_the_budget_comes_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(BUDGET_ENV, raising=False)
    assert budget_bytes() == DEFAULT_BUDGET_MB * 2**20
    monkeypatch.setenv(BUDGET_ENV, "1.5")
    assert budget_bytes() == int(1.5 * 2**20)
    monkeypatch.setenv(BUDGET_ENV, "0")
    assert budget_bytes() == 0
    for bad in ("-1", "lots", "nan"):
        monkeypatch.setenv(BUDGET_ENV, bad)
        with pytest.raises(ValueError, match=BUDGET_ENV):
            budget_bytes()


def _layout(seed: int, size: int = 4, noise: bool = False) -> SolvedLayout:
    """Return a small layout; without `noise` every seed's file has the same size."""
    shape = (3, size, size, 1)
    if noise:
        rng = np.random.default_rng(seed)
        words = rng.integers(0, 2**63, size=13 * 3 * size * size, dtype=np.uint64)
    else:
        words = np.full(13 * 3 * size * size, seed, dtype=np.uint64)
    n = 3 * size * size
    return SolvedLayout(
        words[:n].reshape(shape),
        words[n : 9 * n].reshape((*shape, 8)),
        words[9 * n : 12 * n].reshape((3, *shape)),
        words[12 * n :].reshape(shape),
        levels=seed,
        solve_seconds=1.0,
        threads=1,
    )


def _shapes(shape: tuple[int, ...]) -> tuple[tuple[int, ...], ...]:
    """Return the shapes of a :func:`_layout`'s winning words, planes, viable and safe words."""
    return shape, (*shape, 8), (3, *shape), shape


def _load(store: ControllerStore, key: str) -> SolvedLayout | None:
    return store.load(key, _shapes((3, 4, 4, 1)))


def test_the_least_recently_used_files_go_first(tmp_path: Path) -> None:
    one = ControllerStore(tmp_path, 10**9).save("a", _layout(1))
    assert one is not None
    size = one.stat().st_size
    store = ControllerStore(tmp_path, 3 * size + size // 2)  # 3 files (sizes vary by a byte)
    for age, key in enumerate("abc"):
        store.save(key, _layout(age + 1))
        os.utime(store.path(key), (1000.0 + age, 1000.0 + age))  # a oldest, c newest
    hit = _load(store, "a")  # a hit makes `a` the most recently used
    assert hit is not None
    assert hit.levels == 1
    store.save("d", _layout(4))
    assert not store.path("b").exists()
    assert all(store.path(k).exists() for k in "acd")
    # A stale temporary file of a writer that died goes too; a fresh one stays.
    stale, fresh = tmp_path / ".x.1.tmp", tmp_path / ".y.2.tmp"
    stale.write_bytes(b"partial")
    fresh.write_bytes(b"partial")
    os.utime(stale, (1000.0, 1000.0))
    assert stale in store.evict()
    assert fresh.exists()
    # A file larger than the whole budget is not written; a zero budget writes nothing.
    assert ControllerStore(tmp_path, size - 1).save("e", _layout(5)) is None
    assert ControllerStore(tmp_path / "off", 0).save("e", _layout(5)) is None
    assert not (tmp_path / "off").exists()


@pytest.mark.parametrize("chunk", [16 * 2**20, 1000, 24])
def test_a_stored_layout_reads_back_bit_for_bit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, chunk: int
) -> None:
    # Small frames: frames that end inside an array and frames that span two.
    monkeypatch.setattr(store_module, "_CHUNK", chunk)
    store = ControllerStore(tmp_path, 10**9)
    written = _layout(7, noise=True)
    store.save("k", written)
    read = _load(store, "k")
    assert read is not None
    for a, b in zip(
        (written.winning, written.planes, written.viable, written.safe),
        (read.winning, read.planes, read.viable, read.safe),
        strict=True,
    ):
        np.testing.assert_array_equal(a, b)
        assert b.flags.writeable
        assert b.flags.aligned
        assert b.flags.c_contiguous
    assert (read.levels, read.solve_seconds, read.threads) == (7, 1.0, 1)
    assert store.load("k", _shapes((3, 4, 4, 2))) is None  # other shapes: stale, deleted
    assert not store.path("k").exists()
    store.save("k", written)
    store.path("k").rename(store.path("j"))
    assert _load(store, "j") is None  # a file under another key is not trusted


def _write_many(folder: str, seed: int, n: int) -> None:
    store = ControllerStore(Path(folder), 10**9)
    layout = _layout(seed, size=64, noise=True)
    for _ in range(n):
        store.save("same", layout)


def test_processes_writing_one_key_leave_a_whole_file(tmp_path: Path) -> None:
    context = multiprocessing.get_context("spawn")
    writers = [
        context.Process(target=_write_many, args=(str(tmp_path), 3, 40)) for _ in range(2)
    ]
    for w in writers:
        w.start()
    store = ControllerStore(tmp_path, 10**9)
    reads = 0
    while any(w.is_alive() for w in writers):
        if store.path("same").exists():
            got = store.load("same", _shapes((3, 64, 64, 1)))
            assert got is not None, "a reader saw a partial or damaged file"
            reads += 1
    for w in writers:
        w.join()
        assert w.exitcode == 0
    assert reads > 0
    got = store.load("same", _shapes((3, 64, 64, 1)))
    assert got is not None
    assert got.levels == 3
    assert [p.name for p in tmp_path.iterdir()] == ["same.ctl"]  # no temporary file left
