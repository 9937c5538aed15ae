"""Solved controllers on disk: one compressed file per (solver, tables, layout), size-bounded.

A solve costs seconds (about 20 s for the paper's grid on one core of a loaded 2-core
machine); every ``hil run``, ``hil replay``, ``hil inspect`` and campaign worker on a
layout solved before reads it back instead (:class:`ControllerStore`, used by
:meth:`~hil.controllers.symbolic.synthesis.Synthesizer.solve_problem`).

A file holds the winning bits without their padding, the value bit planes, the
tube-free "viable" words and the safety set's bits (:class:`SolvedLayout`). Layout of
``<folder>/<key>.ctl``::

    b"HILCTL"  format (uint16 LE)  header length (uint32 LE)  header (JSON, UTF-8)
    zstd frames of 16 MiB each: the four arrays back to back (uint64 LE, C order)
    blake2b-256 of every byte before it

Measured on the paper's controller (175 inputs, 160 x 120 x 60 cells), on a loaded
2-core x86_64 machine where its solve took 53 s: 308 MB raw (winning 25.6, planes
205.1, viable 76.9) in a 28 MB file at zstd level 1 (level 3: 1.1 MB smaller, 3x
slower to write; lz4: 47 MB and slower to read here). The viable words compress 85:1
and read in 0.24 s, against 0.85 s to rebuild them from the masks, so they are stored.
Frames decompress in parallel threads (zstd releases the GIL), for the Pi's 4 cores.

The key (:func:`solve_key`) hashes the format, the solver's source files, the tables'
key and the masks, so a file is only ever read for the same problem solved by the same
code; the header repeats the key and the shapes, and the checksum covers the whole file.
A file that fails any check is deleted and the problem re-solved. Writes go to a
temporary file renamed into place (:func:`os.replace`), so processes sharing the folder
never read a partial file; two that write the same key leave one whole file. After each
write the least recently used files (modification time, refreshed on every hit) are
deleted until the folder fits its budget (:data:`BUDGET_ENV`).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import os
import struct
import time
import uuid
from collections.abc import Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import zstandard
from numpy.typing import NDArray

from hil.core.arrays import BoolArray, U64Array

__all__ = [
    "BUDGET_ENV",
    "DEFAULT_BUDGET_MB",
    "FORMAT_VERSION",
    "ControllerStore",
    "SolvedLayout",
    "solve_key",
    "solver_digest",
]


FORMAT_VERSION = 3
"""Layout of a file (header, arrays, checksum); a file of another version is deleted."""

DEFAULT_BUDGET_MB = 4096
"""Total size of the store's files (MiB) unless :data:`BUDGET_ENV` says otherwise.

About 145 of the paper's controllers (28 MB each): a static tank's layout, the layouts of
campaigns and a few moving-obstacle runs (10-40 layouts each) fit together, in a small
share of the Pi's SD card."""

BUDGET_ENV = "HIL_CONTROLLER_CACHE_MB"
"""Environment variable: the store's budget in MiB; 0 turns the store off."""

LEVEL = 1
"""zstd level of the files (compression speed vs size; decompression is fast at any)."""

_MAGIC = b"HILCTL"
_HEAD = struct.Struct("<6sHI")  # magic, format, header length
_DIGEST_BYTES = 32
_SUFFIX = ".ctl"
_CHUNK = 16 * 2**20  # raw bytes per zstd frame (frames decompress in parallel)
_STALE_TMP_S = 3600.0  # a temporary file this old is a writer's that died
# Sources whose change may change a solve's result (the tables' own key covers the
# abstraction; the masks are hashed into the key).
_SOLVER_SOURCES = (
    "synthesis.py", "frontier_kernel.py", "planes_kernel.py", "planes_join.py", "box_test.py",
    "levels.py", "kernels.py", "lattice.py", "safety.py", "safety_kernel.py", "store.py",
    "stored.py", "viable.py",
)


@functools.cache
def solver_digest() -> str:
    """Return a hash of the solver's source files (a new solver never reads old files)."""
    digest = hashlib.sha256()
    here = Path(__file__).resolve().parent
    for name in _SOLVER_SOURCES:
        digest.update(name.encode())
        digest.update((here / name).read_bytes())
    return digest.hexdigest()[:16]


def solve_key(tables_key: str, masks: Sequence[BoolArray]) -> str:
    """Return the key of a solve: the store's format, the solver, the tables and the masks.

    Args:
        tables_key: :attr:`Tables.key <hil.controllers.symbolic.abstraction.Tables.key>`.
        masks: The solve's boolean inputs (free cells per hull range, target cells,
            inflated obstacles), any shapes; shapes and bits are both hashed.
    """
    digest = hashlib.sha256(f"{FORMAT_VERSION}:{solver_digest()}:{tables_key}".encode())
    for mask in masks:
        digest.update(repr(mask.shape).encode())
        digest.update(np.packbits(mask, axis=None).tobytes())
    return digest.hexdigest()


@dataclass(frozen=True, slots=True)
class SolvedLayout:
    """What the fixed point computed for one layout (what a file holds).

    Attributes:
        winning: Winning bits without padding, shape (m, npsi, nw, nx) (bit b of word w
            at (k, i) in layer p: cell (i, 64 w + b, k) wins with reference p).
        planes: Value bit planes, shape (m, npsi, nw, n_planes, nx).
        viable: Tube-free words per class, shape (3, m, npsi, nw, nx) (stored: reading
            them is cheaper than rebuilding them from the masks).
        safe: The safety set's bits without padding, shape (m, npsi, nw, nx)
            (:mod:`~hil.controllers.symbolic.safety`).
        levels: Fixed-point iterations of the solve.
        solve_seconds: Wall time of the solve that produced it (s).
        threads: Threads that solve ran on.
    """

    winning: U64Array
    planes: U64Array
    viable: U64Array
    safe: U64Array
    levels: int
    solve_seconds: float
    threads: int


def budget_bytes() -> int:
    """Return the store's budget from :data:`BUDGET_ENV` (bytes; 0: off).

    Raises:
        ValueError: The variable is not a number of MiB >= 0.
    """
    text = os.environ.get(BUDGET_ENV, "").strip()
    if not text:
        return DEFAULT_BUDGET_MB * 2**20
    try:
        mb = float(text)
    except ValueError:
        mb = -1.0
    if not mb >= 0.0:
        raise ValueError(f"{BUDGET_ENV} must be a size in MiB >= 0, got {text!r}")
    return int(mb * 2**20)


class ControllerStore:
    """Solved layouts under one folder, at most `budget` bytes of files, LRU-evicted.

    Never raises for the state of the folder: an unreadable, corrupt or stale file reads
    as a miss (and is deleted), a write that fails (disk full, read-only) is dropped.

    Args:
        folder: Where the files live (created on the first write).
        budget: Largest total size of the files (bytes); 0 reads and writes nothing.
    """

    def __init__(self, folder: Path, budget: int) -> None:
        self.folder = Path(folder)
        self.budget = max(int(budget), 0)

    @classmethod
    def default(cls, cache_dir: Path | None = None) -> ControllerStore:
        """Return the store under `cache_dir`/controllers, budget from :data:`BUDGET_ENV`.

        Args:
            cache_dir: The table cache folder;
                :func:`~hil.controllers.symbolic.abstraction.default_cache_dir` if None.
        """
        from hil.controllers.symbolic.abstraction import default_cache_dir

        root = default_cache_dir() if cache_dir is None else Path(cache_dir)
        return cls(root / "controllers", budget_bytes())

    @property
    def enabled(self) -> bool:
        """Whether the store reads and writes at all (a budget above 0)."""
        return self.budget > 0

    def path(self, key: str) -> Path:
        """Return the file of `key`."""
        return self.folder / f"{key}{_SUFFIX}"

    def load(self, key: str, shapes: tuple[tuple[int, ...], ...]) -> SolvedLayout | None:
        """Return the layout stored under `key`, or None (missing, corrupt, stale: deleted).

        Args:
            key: :func:`solve_key` of the problem.
            shapes: The shapes the winning words, the value planes, the viable words and
                the safety set's words must have (:class:`SolvedLayout`).
        """
        if not self.enabled:
            return None
        path = self.path(key)
        try:
            data = path.read_bytes()
        except OSError:
            return None
        solved = _decode(data, key, shapes)
        if solved is None:
            _unlink(path)
            return None
        with contextlib.suppress(OSError):
            os.utime(path)  # most recently used
        return solved

    def save(self, key: str, solved: SolvedLayout) -> Path | None:
        """Write `solved` under `key` atomically, then evict down to the budget.

        Returns:
            The file, or None when nothing was written (store off, file over the whole
            budget, or the write failed).
        """
        if not self.enabled:
            return None
        data = _encode(key, solved)
        if len(data) > self.budget:
            return None
        path = self.path(key)
        tmp = self.folder / f".{key}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp"
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            tmp.write_bytes(data)
            os.replace(tmp, path)
        except OSError:
            _unlink(tmp)
            return None
        self.evict(keep=path)
        return path

    def evict(self, keep: Path | None = None) -> list[Path]:
        """Delete the least recently used files until the rest fit the budget.

        Also deletes temporary files of writers that died. Files other processes delete
        meanwhile are skipped.

        Args:
            keep: A file never deleted (the one just written).

        Returns:
            The files deleted.
        """
        entries: list[tuple[float, int, Path]] = []
        gone: list[Path] = []
        now = time.time()
        try:
            listing = list(self.folder.iterdir())
        except OSError:
            return gone
        for p in listing:
            try:
                st = p.stat()
            except OSError:
                continue
            if p.name.endswith(".tmp"):
                if now - st.st_mtime > _STALE_TMP_S and _unlink(p):
                    gone.append(p)
            elif p.suffix == _SUFFIX:
                entries.append((st.st_mtime, st.st_size, p))
        total = sum(size for _, size, _ in entries)
        for _, size, p in sorted(entries, key=lambda e: e[0]):
            if total <= self.budget:
                break
            if p == keep:
                continue
            if _unlink(p):
                gone.append(p)
            total -= size
        return gone


def _unlink(path: Path) -> bool:
    try:
        path.unlink()
    except OSError:
        return False
    return True


def _arrays(solved: SolvedLayout) -> tuple[U64Array, ...]:
    return solved.winning, solved.planes, solved.viable, solved.safe


def _chunks(arrays: Sequence[U64Array], size: int) -> Iterator[bytes | memoryview]:
    """Yield the arrays' bytes back to back in pieces of `size` (the last may be shorter).

    Only a piece that spans two arrays is copied: the paper's 308 MB are never joined.
    """
    pending: list[memoryview] = []
    n = 0
    for a in arrays:
        view = np.ascontiguousarray(a, dtype="<u8").data.cast("B")
        offset = 0
        while offset < len(view):
            take = min(size - n, len(view) - offset)
            pending.append(view[offset : offset + take])
            n += take
            offset += take
            if n == size:
                yield pending[0] if len(pending) == 1 else b"".join(pending)
                pending, n = [], 0
    if pending:
        yield pending[0] if len(pending) == 1 else b"".join(pending)


def _encode(key: str, solved: SolvedLayout) -> bytes:
    cctx = zstandard.ZstdCompressor(level=LEVEL)
    frames = [cctx.compress(piece) for piece in _chunks(_arrays(solved), _CHUNK)]
    header = json.dumps({
        "key": key,
        "shapes": [list(a.shape) for a in _arrays(solved)],
        "frames": [len(f) for f in frames],
        "levels": int(solved.levels),
        "solve_seconds": float(solved.solve_seconds),
        "threads": int(solved.threads),
    }).encode()
    body = b"".join([_HEAD.pack(_MAGIC, FORMAT_VERSION, len(header)), header, *frames])
    return body + hashlib.blake2b(body, digest_size=_DIGEST_BYTES).digest()


def _decode(data: bytes, key: str, shapes: tuple[tuple[int, ...], ...]) -> SolvedLayout | None:
    """Return the layout in `data`, or None when any check fails."""
    if len(data) < _HEAD.size + _DIGEST_BYTES:
        return None
    view = memoryview(data)
    body, digest = view[:-_DIGEST_BYTES], view[-_DIGEST_BYTES:]
    magic, version, n_header = _HEAD.unpack_from(body)
    if magic != _MAGIC or version != FORMAT_VERSION:
        return None
    if hashlib.blake2b(body, digest_size=_DIGEST_BYTES).digest() != digest:
        return None
    try:
        header = json.loads(bytes(body[_HEAD.size : _HEAD.size + n_header]))
        if header["key"] != key or [tuple(x) for x in header["shapes"]] != list(shapes):
            return None
        sizes = [int(np.prod(shape)) * 8 for shape in shapes]
        out = np.empty(sum(sizes), dtype=np.uint8)
        jobs = []
        offset = _HEAD.size + n_header
        for i, n in enumerate(header["frames"]):
            jobs.append((body[offset : offset + n], out[i * _CHUNK : (i + 1) * _CHUNK]))
            offset += n
        if offset != len(body) or len(jobs) != -(-out.size // _CHUNK):
            return None
        # zstd releases the GIL: frames decompress on several cores at once.
        with ThreadPoolExecutor(max_workers=_threads()) as pool:
            if not all(pool.map(_inflate, jobs)):
                return None
    except (ValueError, KeyError, TypeError, zstandard.ZstdError):
        return None
    arrays = []
    start = 0
    for shape, n in zip(shapes, sizes, strict=True):
        arrays.append(out[start : start + n].view(np.uint64).reshape(shape))
        start += n
    return SolvedLayout(
        arrays[0], arrays[1], arrays[2], arrays[3], int(header["levels"]),
        float(header["solve_seconds"]), int(header["threads"]),
    )  # fmt: skip


def _threads() -> int:
    return max(1, min(4, os.cpu_count() or 1))


def _inflate(job: tuple[memoryview, NDArray[np.uint8]]) -> bool:
    """Decompress one frame into its slice of the output; False if it does not fill it."""
    frame, out = job
    view = out.data
    done = 0
    try:
        with zstandard.ZstdDecompressor().stream_reader(frame) as reader:
            while done < out.size:
                n = reader.readinto(view[done:])
                if n == 0:
                    return False
                done += n
            return not reader.read(1)
    except zstandard.ZstdError:
        return False
