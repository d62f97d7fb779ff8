"""Threads of a bag unit's run: the read-ahead thread and each process's scoring pool.

Moved out of :mod:`~dispeval_ros.offline.units` (which re-exports them) to keep it short.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Generator, Iterator
from concurrent.futures import ThreadPoolExecutor
from queue import Full, Queue
from typing import Any, TypeVar

READ_AHEAD = 16
"""Messages read ahead of the scoring (a few frames: each holds its messages in memory)."""
_T = TypeVar("_T")


def scoring_threads(workers: int = 1) -> int:
    """Threads that score a frame's methods in each of ``workers`` processes sharing the cores."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        cores = os.cpu_count() or 1
    return max(1, cores // max(1, workers))


_pools: dict[tuple[int, int], ThreadPoolExecutor] = {}


def scoring_pool(threads: int) -> ThreadPoolExecutor | None:
    """This process's pool of ``threads`` scoring threads, kept across units (None for one)."""
    if threads <= 1:
        return None
    key = (os.getpid(), threads)  # a forked child makes its own: threads do not survive fork
    pool = _pools.get(key)
    if pool is None:
        pool = _pools[key] = ThreadPoolExecutor(threads, thread_name_prefix="dispeval-score")
    return pool


def close_scoring_pools() -> None:
    """Stop this process's scoring threads (a process with threads forks unsafely)."""
    while _pools:
        _pools.popitem()[1].shutdown(wait=True)


def read_ahead(items: Iterator[_T], depth: int = READ_AHEAD) -> Generator[_T, None, None]:
    """``items`` taken on a thread of their own, up to ``depth`` ahead of the caller.

    Reading a bag (file reads, decompression, copies) then overlaps the scoring of the
    frames read before, which releases the GIL in its kernels. What ``items`` raises is
    raised here at the same point of the sequence. The thread has stopped when this
    generator ends or is closed, so the bag is never read by two threads at once.
    """
    queue: Queue[tuple[bool, Any]] = Queue(depth)
    stop = threading.Event()

    def put(entry: tuple[bool, Any]) -> bool:
        while not stop.is_set():
            try:
                queue.put(entry, timeout=0.1)
                return True
            except Full:
                continue
        return False

    def produce() -> None:
        try:
            for item in items:
                if not put((True, item)):
                    return
        except BaseException as error:  # handed to the consumer, raised there
            put((False, error))
            return
        put((False, None))

    thread = threading.Thread(target=produce, name="dispeval-read", daemon=True)
    thread.start()
    try:
        while True:
            is_item, value = queue.get()
            if is_item:
                yield value
            elif value is None:
                return
            else:
                raise value
    finally:
        stop.set()
        thread.join()
