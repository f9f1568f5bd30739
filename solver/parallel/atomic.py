"""What compiled kernels on different threads need to wait for one another: atomic loads and stores, a pause.

A thread of a pipelined sweep (`sweeps.py`) publishes how far it has come with a release store, and another
waits for it with acquire loads: the loads cannot be hoisted out of the waiting loop, and what was written
before the store is seen after the load (the C++ memory model's release/acquire, as LLVM implements it).
numba has no atomics on the CPU, so they are LLVM instructions emitted by numba intrinsics.  `relax` is the
processor's spin-wait hint (x86 ``pause``), and every `YIELD_AFTER` spins the waiting thread gives its core
away (``sched_yield``), so that a wait on a busy machine does not take the time of the thread waited for.
A team (`team.py`) hands its parts over with the same counters, and with `store_and_load` (sequentially
consistent) decides whether a helper that may be falling asleep has to be woken.
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


def _load(ordering: str):
    """An intrinsic: array[index] of an int64 array, an atomic load with `ordering`."""
    def load(typingctx, array, index):
        def codegen(context, builder, signature, args):
            return builder.load_atomic(_pointer(context, builder, signature.args[0], *args), ordering, 8)
        return types.int64(array, index), codegen
    return intrinsic(load)


def _store(ordering: str):
    """An intrinsic: array[index] = value for an int64 array, an atomic store with `ordering`."""
    def store(typingctx, array, index, value):
        def codegen(context, builder, signature, args):
            value = context.cast(builder, args[2], signature.args[2], types.int64)
            builder.store_atomic(value, _pointer(context, builder, signature.args[0], args[0], args[1]), ordering, 8)
            return context.get_dummy_value()
        return types.void(array, index, value), codegen
    return intrinsic(store)


load_acquire, store_release = _load("acquire"), _store("release")  # a release store is seen by an acquire load
# with what was written before it; the sequentially consistent pair are in one total order: of two threads that
# each store one counter and then load the other's, at least one sees the other's store
load_seq_cst, store_seq_cst = _load("seq_cst"), _store("seq_cst")


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
def mark_and_spin(done: np.ndarray, index: int, value: int, progress: np.ndarray, least: int, spins: int) -> bool:
    """done[index, 0] = value (release; nothing if value is 0), then spin at most `spins` times until
    progress[index, 0] >= least; whether it got there.  One call without the GIL: the thread waiting for `done`
    does not then wait for this one's interpreter lock as well."""
    if value:
        store_release(done[index], 0, value)
    return _spin(progress, index, least, spins)


@numba.njit(cache=True, nogil=True)
def store_and_load(stored: np.ndarray, index: int, value: int, loaded: np.ndarray) -> int:
    """stored[index, 0] = value, then loaded[index, 0], both sequentially consistent: of two threads that each
    store one counter and then load the other's, at least one sees the other's store (a helper that raises its
    flag before it sleeps, and the caller that hands it a part and then looks at that flag)."""
    store_seq_cst(stored[index], 0, value)
    return load_seq_cst(loaded[index], 0)


@numba.njit(cache=True, nogil=True)
def wait_until(progress: np.ndarray, index: int, least: int) -> None:
    """Spin until progress[index, 0] >= least (rows of progress on cache lines of their own)."""
    while not _spin(progress, index, least, YIELD_AFTER):
        pass


@numba.njit(inline="always")
def _spin(progress, index, least, spins):
    """Spin at most `spins` times until progress[index, 0] >= least, giving the core away (``sched_yield``) every
    `YIELD_AFTER`-th; whether it got there."""
    for spin in range(1, spins + 1):
        if load_acquire(progress[index], 0) >= least:
            return True
        if spin % YIELD_AFTER:
            relax()
        else:
            sched_yield()
    return load_acquire(progress[index], 0) >= least
