"""Software prefetch for compiled kernels: ask for cache lines a few steps before use.

The bit-plane fixed point touches short bands (20-60 words) of rows scattered over
arrays far larger than the last-level cache (viable words, the winning bits, the value
planes: 50-190 MB each at the paper grid), one band per (input, heading) slab; each band
is a cache miss the hardware prefetcher cannot predict, and the kernel waited for them
(a level ran 1.6x slower than with those arrays cache-resident). The kernel knows the
next slab's bands before it starts the current one, so it asks for them here: LLVM's
``llvm.prefetch`` (x86 PREFETCHT0, aarch64 PRFM), a hint that never faults and changes
no result.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, cast

from llvmlite import ir  # type: ignore[import-untyped]
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from hil.core.arrays import U64Array
from hil.core.jit import njit_inline

__all__ = ["prefetch", "prefetch_rows"]

_LINE_WORDS = 8
"""64-bit words per 64-byte cache line (x86-64 and the Pi's Cortex-A72 alike)."""


@intrinsic
def _prefetch(typingctx: Any, array: Any, index: Any) -> Any:  # noqa: ARG001 (numba's signature)
    """Hint that array[index] (a 1-D array, any index inside it) is read soon.

    Compiled code only (a numba intrinsic): a call from Python raises.
    """
    if not (isinstance(array, types.Array) and array.ndim == 1) or not isinstance(
        index, types.Integer
    ):
        return None
    signature = types.void(array, index)

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        array_type = sig.args[0]
        view = context.make_array(array_type)(context, builder, args[0])
        at = context.cast(builder, args[1], sig.args[1], types.intp)
        pointer = cgutils.get_item_pointer(  # type: ignore[no-untyped-call]
            context, builder, array_type, view, [at], wraparound=False
        )
        byte_pointer = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        hint = cgutils.get_or_insert_function(  # type: ignore[no-untyped-call]
            builder.module,
            ir.FunctionType(ir.VoidType(), [byte_pointer, i32, i32, i32]),
            "llvm.prefetch.p0",
        )
        # read (0), keep in every cache level (3), data cache (1)
        builder.call(hint, [builder.bitcast(pointer, byte_pointer), i32(0), i32(3), i32(1)])
        return context.get_dummy_value()

    return signature, codegen


prefetch = cast(Callable[[U64Array, int], None], _prefetch)
"""Hint that array[index] (a 1-D array, any index inside it) is read soon (compiled code)."""


@njit_inline
def prefetch_rows(row: U64Array, lo: int, hi: int) -> None:
    """Prefetch the cache lines of row[lo .. hi] (a 1-D word array; lo > hi: none)."""
    if lo > hi:
        return
    for i in range(lo, hi + 1, _LINE_WORDS):
        prefetch(row, i)
    prefetch(row, hi)
