"""Hand-offs between the master's thread and its stage threads without a sleep in between.

A thread that waits on a lock or condition sleeps in the kernel, and waking it costs tens of
microseconds on the machines we run on (a virtual CPU that went idle: 20-25 us measured per
wake-up, ``threading.Event`` ping-pong 43 us a round trip). A threaded stage of the master
(:mod:`.threads`) hands work over twice per macro step, so these wake-ups were ~5 % of a
0.1 ms macro step of the free-to-air run-up. Here a waiting thread instead watches a flag in
a compiled loop that holds no GIL, for a bounded number of turns, and only then sleeps: the
other thread sees the flag within a fraction of a microsecond, and, as the waiting thread
holds no GIL, the one that finishes its Python work finds the GIL free.

The flags are int64 slots of a numpy array, read and written with atomic loads and stores
(acquire / release; the compiled loop must not keep the slot in a register). The Python side
writes a slot with a plain numpy store while it holds the GIL, which is a full barrier.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

#: turns of the watching loop before a waiting thread goes to sleep (a few milliseconds: longer
#: than the master's serial work between two stages, shorter than anything a user would notice
#: as a busy core once a run is idle)
SPIN_TURNS = 4_000_000


@intrinsic
def _load(typingctx, arr, idx):
    """``arr[idx]`` by an atomic load with acquire ordering (an int64 array)."""
    if not (isinstance(arr, types.Array) and arr.dtype == types.int64):
        return None
    sig = types.int64(arr, types.intp)

    def codegen(context, builder, sig, args):
        aryty = sig.args[0]
        ary = context.make_array(aryty)(context, builder, args[0])
        ptr = cgutils.get_item_pointer(context, builder, aryty, ary, [args[1]])
        return builder.load_atomic(ptr, "acquire", 8)
    return sig, codegen


@intrinsic
def _store(typingctx, arr, idx, value):
    """``arr[idx] = value`` by an atomic store with release ordering (an int64 array)."""
    if not (isinstance(arr, types.Array) and arr.dtype == types.int64):
        return None
    sig = types.void(arr, types.intp, types.int64)

    def codegen(context, builder, sig, args):
        aryty = sig.args[0]
        ary = context.make_array(aryty)(context, builder, args[0])
        ptr = cgutils.get_item_pointer(context, builder, aryty, ary, [args[1]])
        builder.store_atomic(args[2], ptr, "release", 8)
        return context.get_dummy_value()
    return sig, codegen


@nb.njit(cache=True, nogil=True)
def watch(flags, k, value, turns):
    """True as soon as ``flags[k] == value``; False after ``turns`` turns without it (the
    slot is looked at once at least)."""
    for _ in range(max(turns, 1)):
        if _load(flags, k) == value:
            return True
    return False


@nb.njit(cache=True, nogil=True)
def post_and_watch(flags, k, posted, value, turns):
    """``flags[k] = posted`` (atomic, after everything this thread wrote), then :func:`watch`
    for ``value``: the GIL is already released when the other thread sees ``posted``."""
    _store(flags, k, posted)
    return watch(flags, k, value, turns)


def new_flags(n: int) -> np.ndarray:
    """``n`` flag slots, each on its own cache line (64 bytes), all 0."""
    return np.zeros(8 * max(n, 1), dtype=np.int64)
