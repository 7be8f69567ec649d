"""What building a node's robot model leaves in the process, given back before the node serves.

A G1 model with its visual meshes is compiled twice in ``/sim`` and in ``/arm`` (by
``robot_models.load``, once more for the arms' IK): hundreds of MB of buffers that live a moment. glibc
keeps freed heap memory for reuse, and buffers freed between long-lived objects fragment the heap;
MuJoCo keeps every mesh it read in its asset cache. Both only grow a node's resident memory.
"""

from __future__ import annotations

import ctypes
import sys

M_MMAP_THRESHOLD = -3  # glibc's mallopt parameter (malloc.h)
LARGE_BUFFER_BYTES = 256 * 1024  # [B] allocations from this size on get pages of their own


def _glibc() -> ctypes.CDLL | None:
    try:
        return ctypes.CDLL("libc.so.6")
    except OSError:  # not glibc: its allocator is left as it is
        return None


def map_large_buffers() -> None:
    """From now on, large allocations get pages of their own, returned to the system when freed.

    Call it before the node builds its model: the compiler's large, short-lived buffers then leave
    no holes in the heap (glibc otherwise raises its threshold after the first such buffer is freed,
    up to 32 MB). An idle server allocates few buffers that large.
    """
    libc = _glibc()
    if libc is not None:
        libc.mallopt(M_MMAP_THRESHOLD, LARGE_BUFFER_BYTES)


def release_build_memory() -> None:
    """Once the node is built: empty MuJoCo's asset cache and give the heap's free pages back.

    A built node compiles no model again (~110 MB of G1 meshes in the cache). A node that never
    imported mujoco has no cache to empty.
    """
    mujoco = sys.modules.get("mujoco")
    if mujoco is not None:
        mujoco.mj_clearCache(mujoco.mj_getCache())
    libc = _glibc()
    if libc is not None:
        libc.malloc_trim(0)
