"""Frame-sized arrays kept on the heap: glibc tuned once per process that scores units."""

from __future__ import annotations

import ctypes
import sys

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc's mallopt parameters
HEAP_ARRAYS_BYTES = 64 << 20
"""Arrays up to this size come from the heap, and up to twice it stays mapped when freed."""
_allocator: dict[str, bool] = {}


def keep_frames_on_the_heap() -> None:
    """Let glibc reuse the heap for frame-sized arrays (once per process; Linux only).

    A unit allocates and frees arrays of a few MB per frame. When glibc maps each one afresh,
    every use pays page faults: a unit runs 2–3× slower, as in Dask workers, whose nanny sets
    ``MALLOC_TRIM_THRESHOLD_`` (which freezes glibc's adaptive mmap threshold), and still
    ~20 % slower with glibc's defaults (measured with bench/bench_bag.py, bench_dask.py).
    """
    if _allocator or not sys.platform.startswith("linux"):
        return
    _allocator["tuned"] = True
    try:
        mallopt = ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):  # not glibc: nothing to tune
        return
    mallopt(_M_MMAP_THRESHOLD, HEAP_ARRAYS_BYTES)
    mallopt(_M_TRIM_THRESHOLD, 2 * HEAP_ARRAYS_BYTES)
