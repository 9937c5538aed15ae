"""The one place that decides how numerical kernels are compiled.

Every kernel in the package is decorated with :func:`njit` from here, so the
compilation options (on-disk cache for a fast second start, no fastmath so that
IEEE semantics and therefore the soundness arguments hold) are set once.

numba's cache checks only the source file of the function it compiled, not the
files of the kernels it calls: after an edit to a callee, a cached caller would
silently run the old code. So the cache lives in a folder named by a hash of
every source file of the package: any edit starts a fresh cache, and the folders
of older sources are pruned.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar, cast

import numba

F = TypeVar("F", bound=Callable[..., Any])

_PACKAGE = Path(__file__).resolve().parent.parent  # the whole hil package
_KEEP = 8  # cache folders of older sources kept (switching branches, parallel checkouts)


def _sources_digest() -> str:
    digest = hashlib.sha256(numba.__version__.encode())
    for path in sorted(_PACKAGE.rglob("*.py")):
        digest.update(path.relative_to(_PACKAGE).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def cache_root() -> Path:
    """Return the folder holding the per-source cache folders.

    `HIL_NUMBA_CACHE_DIR`, else numba's own `NUMBA_CACHE_DIR`, else
    `~/.cache/hil/numba`.
    """
    configured = os.environ.get("HIL_NUMBA_CACHE_DIR") or os.environ.get("NUMBA_CACHE_DIR")
    return Path(configured) if configured else Path.home() / ".cache" / "hil" / "numba"


def _configure_cache() -> Path:
    folder = cache_root() / _sources_digest()
    folder.mkdir(parents=True, exist_ok=True)
    os.utime(folder)  # mark as recently used
    siblings = sorted((p for p in folder.parent.iterdir() if p.is_dir() and p != folder),
                      key=lambda p: p.stat().st_mtime, reverse=True)
    for old in siblings[_KEEP:]:
        shutil.rmtree(old, ignore_errors=True)
    numba.config.CACHE_DIR = str(folder)  # type: ignore[attr-defined]
    return folder


CACHE_DIR = _configure_cache()
"""Where compiled kernels of this exact source tree are cached."""


def njit(fn: F) -> F:
    """Compile `fn` with numba in nopython mode, cached on disk, keeping its type."""
    return cast(F, numba.njit(cache=True, nogil=True)(fn))


def njit_inline(fn: F) -> F:
    """Like :func:`njit`, and inlined into each numba caller (numba IR, before LLVM).

    For the steps of a hot kernel: a call of a compiled function passes every array as
    a struct and counts its references, 20-50 ns that thousands of short loops per BFS
    level would pay (a split box test ran 6 % slower per level without it).
    """
    return cast(F, numba.njit(cache=True, nogil=True, inline="always")(fn))


def njit_parallel(fn: F) -> F:
    """Like :func:`njit` but allows `numba.prange` loops over threads."""
    return cast(F, numba.njit(cache=True, nogil=True, parallel=True)(fn))


def thread_limit(threads: int) -> int:
    """Return how many of numba's threads a kernel asked to run on `threads` may use.

    Between 1 and NUMBA_NUM_THREADS (the pool's size, fixed at start-up).
    """
    return max(1, min(int(threads), int(numba.config.NUMBA_NUM_THREADS)))  # type: ignore[attr-defined]


@contextlib.contextmanager
def numba_threads(threads: int) -> Iterator[int]:
    """Run numba's parallel kernels on :func:`thread_limit` (threads) threads in the block.

    Yields that count; the pool's previous setting is restored on leaving, whatever happens.
    """
    count = thread_limit(threads)
    previous = numba.get_num_threads()
    numba.set_num_threads(count)
    try:
        yield count
    finally:
        numba.set_num_threads(previous)


@contextlib.contextmanager
def cache_lock() -> Iterator[None]:
    """Hold this source tree's cache folder exclusively (blocks until free).

    Worker processes that start together warm under it: the first compiles and
    writes the kernels, the others wait and then load them, instead of all compiling
    the same kernels at once and racing to write the same cache files. Where file
    locks are missing (not POSIX) it holds nothing.
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield
        return
    with (CACHE_DIR / ".warm.lock").open("a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def kernels_cached() -> bool:
    """Return True when numba's cache of this source tree holds compiled kernels.

    False means the next kernel calls compile (the first run after an edit of the
    package); commands say so before the wait.
    """
    return any(CACHE_DIR.rglob("*.nbi"))


def _marker(key: str) -> Path:
    return CACHE_DIR / f".warmed-{hashlib.sha256(key.encode()).hexdigest()[:16]}"


def warmed(key: str) -> bool:
    """Return True once a :func:`warm_once` of `key` has finished against this cache."""
    return _marker(key).exists()


def warm_once(key: str, warm: Callable[[], None]) -> None:
    """Run `warm` (code that compiles kernels); the first process to do so holds the lock.

    Double-checked: once a warm of `key` has finished against this cache, later ones
    only load kernels (no write, no race) and run side by side; until then they queue
    on :func:`cache_lock`, so one process compiles and the others load its kernels.

    Args:
        key: Names what `warm` compiles (e.g. the function and its arguments).
        warm: The warm-up.
    """
    marker = _marker(key)
    if marker.exists():
        warm()
        return
    with cache_lock():
        warm()
        marker.touch()
