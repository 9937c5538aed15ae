"""How much memory this process may still allocate, checked before a large allocation.

Linux overcommits: a numpy array larger than the free memory is handed out and the
process is killed (no message, nothing saved) when its pages are touched, as a synthesis
on too fine a grid would be on the vessel's 8-GB Pi. Work that knows its size up front
asks here first and fails with a readable error instead.
"""

from __future__ import annotations

import resource
from pathlib import Path

__all__ = ["available_bytes", "require_bytes"]

_MEMINFO = Path("/proc/meminfo")
_STATUS = Path("/proc/self/status")


def _kib_field(path: Path, name: str) -> int | None:
    """Return the `name:` line of a /proc file in bytes (its value is in kB), None if absent."""
    try:
        text = path.read_text()
    except OSError:
        return None
    for line in text.splitlines():
        if line.startswith(name + ":"):
            parts = line.split()
            if len(parts) >= 2 and parts[1].isdigit():
                return int(parts[1]) * 1024
    return None


def available_bytes() -> int | None:
    """Return the bytes this process can still allocate, None where it cannot be told.

    The least of the system's available memory (MemAvailable plus free swap) and the
    headroom under the process's address-space limit (RLIMIT_AS less its current size).
    """
    limits: list[int] = []
    mem = _kib_field(_MEMINFO, "MemAvailable")
    if mem is not None:
        limits.append(mem + (_kib_field(_MEMINFO, "SwapFree") or 0))
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY:
        size = _kib_field(_STATUS, "VmSize") or 0
        limits.append(max(soft - size, 0))
    return min(limits) if limits else None


def require_bytes(needed: int, what: str) -> None:
    """Raise MemoryError when `needed` bytes are more than :func:`available_bytes`.

    Args:
        needed: Bytes the work will allocate (an estimate from its array shapes).
        what: The work, for the message ("a solve on the 160 x 120 x 60 grid").

    Raises:
        MemoryError: Not enough memory; the message gives both sizes in GiB.
    """
    available = available_bytes()
    if available is not None and needed > available:
        raise MemoryError(
            f"{what} needs about {needed / 2**30:.1f} GiB, "
            f"{available / 2**30:.1f} GiB available"
        )
