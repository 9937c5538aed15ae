"""The one place that decides how numerical kernels are compiled.

Every kernel in the package is decorated with :func:`njit` from here, so the
compilation options (on-disk cache for a fast second start, no fastmath so that
IEEE semantics and therefore the soundness arguments hold) are set once.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

import numba

F = TypeVar("F", bound=Callable[..., Any])


def njit(fn: F) -> F:
    """Compile `fn` with numba in nopython mode, cached on disk, keeping its type."""
    return cast(F, numba.njit(cache=True, nogil=True)(fn))


def njit_parallel(fn: F) -> F:
    """Like :func:`njit` but allows `numba.prange` loops over threads."""
    return cast(F, numba.njit(cache=True, nogil=True, parallel=True)(fn))
