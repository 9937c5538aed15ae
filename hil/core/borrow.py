"""Borrowed array views for compiled kernels: slices without reference counting.

Every slice numba makes of an array (``W[u, k, w, lo:hi]``) shares its owner's memory
record and counts itself in with an atomic increment, and out with an atomic decrement
when it is dropped. A bit-plane kernel makes several slices per (input, heading) slab,
tens of thousands per BFS level, and those locked operations also stall the core's
outstanding loads: they took 40 % of a level's samples at the paper grid (``perf``), and
a level ran in 0.71x the time without them.

:func:`borrowed` returns a view of the same memory with no memory record, so that slices
of it count nothing. It does not keep its memory alive, so it is safe only where the owner
provably outlives it:

- a kernel's own parameters (the caller holds them for the whole call): rebind them at
  entry, ``W = borrowed(W)``;
- an array the kernel allocates: hand the view to a call in the same statement that holds
  the owner, ``_work(borrowed(scratch))``, so that the owner is released only after it.

Never store a borrowed view in a container or return it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ["borrowed"]

_A = TypeVar("_A")


@intrinsic
def _borrowed(typingctx: Any, array: Any) -> Any:  # noqa: ARG001 (numba's signature)
    """Return a view of `array` (any numba array) without its memory record."""
    if not isinstance(array, types.Array):
        return None
    signature = array(array)

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        array_type = sig.args[0]
        owner = context.make_array(array_type)(context, builder, value=args[0])
        view = context.make_array(array_type)(context, builder)
        view.meminfo = cgutils.get_null_value(view.meminfo.type)  # type: ignore[no-untyped-call]
        view.parent = cgutils.get_null_value(view.parent.type)  # type: ignore[no-untyped-call]
        view.nitems = owner.nitems
        view.itemsize = owner.itemsize
        view.data = owner.data
        view.shape = owner.shape
        view.strides = owner.strides
        return view._getvalue()

    return signature, codegen


borrowed = cast(Callable[[_A], _A], _borrowed)
"""A view of the array without its memory record (compiled code; see the module)."""
