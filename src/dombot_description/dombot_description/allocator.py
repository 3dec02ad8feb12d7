"""glibc allocator settings for nodes that take huge requests.

A request of 10,000 poses or 100,000 points becomes hundreds of thousands of Python
objects and big buffers on one of the executor's threads. With glibc's defaults the
memory stays with the process after the reply: each thread gets its own malloc arena
(up to 8 per core), and after each big block freed glibc raises its mmap threshold so the
next big blocks are carved from those heaps, where fragments pin them
(docs/RELIABILITY.md, "Memory").
"""

from __future__ import annotations

import ctypes

LIBC = ctypes.CDLL("libc.so.6")
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD, M_ARENA_MAX = -1, -3, -8  # mallopt parameters (malloc.h)
MMAP_THRESHOLD = 128 * 1024  # bytes: glibc's initial value, kept fixed


def tune_allocator() -> None:
    """Two malloc arenas for all threads and a fixed 128 KiB mmap threshold (big blocks
    mapped and unmapped on their own). Call before the node starts threads."""
    LIBC.mallopt(M_ARENA_MAX, 2)
    LIBC.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)


def set_mmap_threshold(size: int) -> None:
    """Map blocks of ``size`` bytes and more on their own, and keep up to twice that free at
    the heap's top (glibc's own ratio when it moves the threshold itself).

    For a process that allocates and frees a few blocks above 128 KiB many times a second
    (a Drake plant's dense matrices every physics step): mapped on their own, each costs a
    ``mmap``, page faults that zero it and a ``munmap``; carved from the heap with the top
    trimmed at 128 KiB (glibc's default once the threshold is fixed), each trim and regrowth
    faults the pages in again."""
    LIBC.mallopt(M_MMAP_THRESHOLD, size)
    LIBC.mallopt(M_TRIM_THRESHOLD, 2 * size)


def release_memory() -> None:
    """Hand the free pages of every arena back to the system after a big reply (a
    400-domino /plan_place left ~25 MB of freed Drake contexts with glibc otherwise)."""
    LIBC.malloc_trim(0)
