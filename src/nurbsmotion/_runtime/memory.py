"""Giving freed memory back to the system (private).

glibc's allocator serves a request below its mmap threshold from the heap, and raises that
threshold (up to 32 MB) each time it frees a larger mmapped block; so the second and later
large temporaries of a computation come from the heap, and once freed the process keeps
them. ``planned``'s plan of a 10-minute move frees tens of MB of them before its run
starts, and the run's peak resident set sat on top of them (`benchmarks/long_run.py`:
297 MB with ``trace.parquet``; 275 MB once they are handed back).
:func:`release_freed_memory` hands them back (``malloc_trim``); on a C library without it
it does nothing.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools

__all__ = ["release_freed_memory"]


@functools.cache
def _malloc_trim():
    """glibc's ``malloc_trim``, or None."""
    name = ctypes.util.find_library("c")
    if name is None:
        return None
    try:
        return getattr(ctypes.CDLL(name), "malloc_trim", None)
    except OSError:
        return None


def release_freed_memory() -> bool:
    """Return the heap's free memory to the system; True if the C library could."""
    trim = _malloc_trim()
    if trim is None:
        return False
    trim(0)
    return True
