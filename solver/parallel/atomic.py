"""What compiled kernels on different threads need to wait for one another: atomic loads and stores, a pause.

A thread of a pipelined sweep (`sweeps.py`) publishes how far it has come with a release store, and another
waits for it with acquire loads: the loads cannot be hoisted out of the waiting loop, and what was written
before the store is seen after the load (the C++ memory model's release/acquire, as LLVM implements it).
numba has no atomics on the CPU, so they are LLVM instructions emitted by numba intrinsics.  `relax` is the
processor's spin-wait hint (x86 ``pause``), and every `YIELD_AFTER` spins the waiting thread gives its core
away (``sched_yield``), so that a wait on a busy machine does not take the time of the thread waited for.
"""
from __future__ import annotations

import platform

import numba
import numpy as np
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

YIELD_AFTER = 256  # spins before a waiting thread gives its core away
X86 = platform.machine().lower() in ("x86_64", "amd64", "i386", "i686")
sched_yield = types.ExternalFunction("sched_yield", types.int32())


def _pointer(context, builder, array_type, array, index):
    data = context.make_array(array_type)(context, builder, array)
    return cgutils.get_item_pointer(context, builder, array_type, data, [index], wraparound=False)


@intrinsic
def load_acquire(typingctx, array, index):
    """array[index] of an int64 array, an atomic load with acquire ordering."""
    def codegen(context, builder, signature, args):
        return builder.load_atomic(_pointer(context, builder, signature.args[0], *args), "acquire", 8)
    return types.int64(array, index), codegen


@intrinsic
def store_release(typingctx, array, index, value):
    """array[index] = value for an int64 array, an atomic store with release ordering."""
    def codegen(context, builder, signature, args):
        value = context.cast(builder, args[2], signature.args[2], types.int64)
        builder.store_atomic(value, _pointer(context, builder, signature.args[0], args[0], args[1]), "release", 8)
        return context.get_dummy_value()
    return types.void(array, index, value), codegen


@intrinsic
def relax(typingctx):
    """The processor's hint that this is a spin-wait (x86 ``pause``; nothing elsewhere)."""
    def codegen(context, builder, signature, args):
        if X86:
            hint = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), []),
                                                  "llvm.x86.sse2.pause")
            builder.call(hint, [])
        return context.get_dummy_value()
    return types.void(), codegen


@numba.njit(cache=True, nogil=True)
def wait_until(progress: np.ndarray, index: int, least: int) -> None:
    """Spin until progress[index, 0] >= least (rows of progress on cache lines of their own)."""
    spins = 0
    while load_acquire(progress[index], 0) < least:
        spins += 1
        if spins % YIELD_AFTER:
            relax()
        else:
            sched_yield()
