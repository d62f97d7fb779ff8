"""Compiled non-dominated sorting on integer ranks: no method × method matrix is ever built.

Every objective is first replaced by its dense rank (equal values share a rank, NaN is already
``+inf``, ``-0.0`` equals ``0.0``), so dominance is exact integer comparison and ties, duplicate
rows and signed zeros need no special case. Methods are then inserted one at a time into the
fronts found so far, in an order where a dominator always comes first:

* two objectives: lexicographic order, where the fronts' smallest second objective increases
  with the front index, so each method's front is a binary search (``O(N log N)``);
* more: ascending sum of ranks (a dominator has a strictly smaller sum), duplicate rows sorted
  once, and the method's front found by binary search over the fronts (ENS-BS, Zhang et al.
  2015). A front's members are kept in small blocks with their per-objective minimum, so a
  block is skipped when the method is better than all its members on some objective;
  otherwise members are compared with an early exit.

The compiled functions are only compiled when a model is first evaluated with more than
:data:`SMALL_PROBLEM` methods (numba compiles lazily and caches on disk); fewer methods, the
common case of a handful of stereo methods, use the dominance table directly and need no
compilation at all.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dispeval_ros.jitcache import ensure_cache_location

ensure_cache_location()  # before any kernel is decorated with cache=True

# Up to this many methods a methods × methods dominance table is cheaper than compiling.
SMALL_PROBLEM = 32

# Members of a front are kept in blocks of this many rows (their ranks copied contiguously),
# each with its per-objective minimum: a block none of whose members can dominate a method is
# skipped with one comparison per objective.
_BLOCK = 16


@njit(cache=True, nogil=True)
def _twins(
    ranks: np.ndarray, by_hash: np.ndarray, hashes: np.ndarray
) -> np.ndarray:  # pragma: no cover
    """For every row, the first row with identical ranks (itself when it is unique).

    ``by_hash`` orders the rows by ``hashes`` (equal rows have equal hashes; rows with equal
    hashes are compared exactly).
    """
    n, m = ranks.shape
    twin = np.empty(n, dtype=np.int64)
    for i in range(n):
        twin[i] = i
    start = 0
    while start < n:
        stop = start + 1
        while stop < n and hashes[by_hash[stop]] == hashes[by_hash[start]]:
            stop += 1
        for a in range(start, stop):
            i = by_hash[a]
            if twin[i] != i:
                continue
            for b in range(a + 1, stop):
                k = by_hash[b]
                if twin[k] == k:
                    same = True
                    for j in range(m):
                        if ranks[i, j] != ranks[k, j]:
                            same = False
                            break
                    if same:
                        twin[k] = i
        start = stop
    return twin


@njit(cache=True, nogil=True)
def _dominated_by_front(
    row: np.ndarray,
    row_sum: int,
    first_block: int,
    block_rows: np.ndarray,
    block_sums: np.ndarray,
    block_min: np.ndarray,
    block_size: np.ndarray,
    next_block: np.ndarray,
) -> bool:  # pragma: no cover - compiled
    """Whether a member of the front starting at ``first_block`` dominates ``row``.

    Every member precedes ``row`` in sum order, so ``t ≤ row`` everywhere with a smaller sum
    is dominance; oldest blocks first (the smallest sums, the likeliest dominators).
    """
    m = row.shape[0]
    b = first_block
    while b >= 0:
        possible = True
        for j in range(m):
            if row[j] < block_min[b, j]:  # better than every member of the block here
                possible = False
                break
        if possible:
            for k in range(block_size[b]):
                if block_sums[b, k] < row_sum:  # an equal sum is an incomparable row
                    dominated = True
                    for j in range(m):
                        if block_rows[b, k, j] > row[j]:
                            dominated = False
                            break
                    if dominated:
                        return True
        b = next_block[b]
    return False


def fronts_small(ranks: np.ndarray, first_only: bool) -> np.ndarray:
    """Front numbers of a few rows from their dominance table (peeled by dominator counts)."""
    n = ranks.shape[0]
    weakly = np.all(ranks[:, None, :] <= ranks[None, :, :], axis=2)
    dominance = weakly & ~weakly.T
    dominators = dominance.sum(axis=0)
    result = np.zeros(n, dtype=np.int64)
    remaining = np.ones(n, dtype=np.bool_)
    front = 0
    while remaining.any():  # a strict partial order: a non-empty set always has a front
        front += 1
        members = remaining & (dominators == 0)
        result[members] = front
        remaining &= ~members
        if first_only:
            result[remaining] = 2
            break
        dominators = dominators - dominance[members].sum(axis=0)
    return result


def fronts_by_sum(ranks: np.ndarray, first_only: bool) -> np.ndarray:
    """Front number (1 = non-dominated) of every row of ``ranks`` (int32, rows × objectives).

    ``first_only`` stops at A*: every dominated row gets 2. Duplicate rows are sorted once.
    The sorts run in numpy (a sort compiled by numba costs seconds of JIT time).
    """
    n = ranks.shape[0]
    sums = ranks.sum(axis=1, dtype=np.int64)
    order = np.argsort(sums, kind="stable")
    hashes = np.full(n, 0xCBF29CE484222325, dtype=np.uint64)
    for column in ranks.T:  # FNV-1a over the ranks (wrapping uint64 arithmetic)
        hashes = (hashes ^ column.astype(np.uint64)) * np.uint64(0x100000001B3)
    twin = _twins(ranks, np.argsort(hashes, kind="stable"), hashes)
    capacity = n // _BLOCK + 64
    while True:  # blocks needed: at most n / _BLOCK full ones plus one part-filled per front
        result = _insert_sorted(ranks, sums, order, twin, first_only, capacity)
        if result[0] >= 0:
            return result
        capacity = n + n // _BLOCK + 1


@njit(cache=True, nogil=True)
def _insert_sorted(
    ranks: np.ndarray,
    sums: np.ndarray,
    order: np.ndarray,
    twin: np.ndarray,
    first_only: bool,
    capacity: int,
) -> np.ndarray:  # pragma: no cover - compiled
    """Fronts by inserting rows in ``order`` (ascending ``sums``); ``[-1]`` when out of blocks."""
    n, m = ranks.shape
    result = np.zeros(n, dtype=np.int64)
    block_rows = np.empty((capacity, _BLOCK, m), dtype=np.int32)
    block_sums = np.empty((capacity, _BLOCK), dtype=np.int64)
    block_min = np.empty((capacity, m), dtype=np.int32)
    block_size = np.zeros(capacity, dtype=np.int64)
    next_block = np.empty(capacity, dtype=np.int64)
    first_block = np.empty(n, dtype=np.int64)  # per front
    last_block = np.empty(n, dtype=np.int64)
    n_blocks = 0
    n_fronts = 0
    for p in range(n):
        s = order[p]
        if twin[s] != s:
            continue
        row = ranks[s]
        low = 0
        high = min(n_fronts, 1) if first_only else n_fronts
        while low < high:  # dominated by front k ⇒ dominated by every front before k
            middle = (low + high) // 2
            if _dominated_by_front(
                row,
                sums[s],
                first_block[middle],
                block_rows,
                block_sums,
                block_min,
                block_size,
                next_block,
            ):
                low = middle + 1
            else:
                high = middle
        result[s] = low + 1
        if first_only and low > 0:
            continue
        b = -1
        if low == n_fronts:
            n_fronts += 1
        else:
            b = last_block[low]
        if b < 0 or block_size[b] == _BLOCK:
            if n_blocks == capacity:
                result[0] = -1
                return result
            b_new = n_blocks
            n_blocks += 1
            next_block[b_new] = -1
            for j in range(m):
                block_min[b_new, j] = row[j]
            if b < 0:
                first_block[low] = b_new
            else:
                next_block[b] = b_new
            last_block[low] = b_new
            b = b_new
        k = block_size[b]
        for j in range(m):
            block_rows[b, k, j] = row[j]
            block_min[b, j] = min(block_min[b, j], row[j])
        block_sums[b, k] = sums[s]
        block_size[b] = k + 1
    for i in range(n):
        result[i] = result[twin[i]]
    return result


@njit(cache=True, nogil=True)
def _counting_order(keys: np.ndarray, order: np.ndarray) -> np.ndarray:  # pragma: no cover
    """Reorder ``order`` stably by ``keys[order]`` (dense ranks in ``[0, n)``): a counting sort."""
    n = keys.shape[0]
    starts = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):
        starts[keys[i] + 1] += 1
    for k in range(n):
        starts[k + 1] += starts[k]
    result = np.empty(n, dtype=np.int64)
    for i in order:
        key = keys[i]
        result[starts[key]] = i
        starts[key] += 1
    return result


@njit(cache=True, nogil=True)
def fronts_two(
    first: np.ndarray, second: np.ndarray, first_only: bool
) -> np.ndarray:  # pragma: no cover
    """Front number of every point ``(first[i], second[i])`` (int32 ranks) by one sweep.

    In lexicographic order a point is dominated by a front exactly when the front's smallest
    ``second`` is not larger than its own, and that smallest value increases with the front.
    """
    n = first.shape[0]
    identity = np.empty(n, dtype=np.int64)
    for i in range(n):
        identity[i] = i
    order = _counting_order(first, _counting_order(second, identity))
    result = np.zeros(n, dtype=np.int64)
    smallest = np.empty(n, dtype=np.int64)  # smallest `second` of each front
    n_fronts = 0
    previous = -1
    for p in range(n):
        s = order[p]
        if previous >= 0 and first[s] == first[previous] and second[s] == second[previous]:
            result[s] = result[previous]  # a duplicate shares its twin's front
            continue
        previous = s
        value = second[s]
        searched = min(n_fronts, 1) if first_only else n_fronts
        low = np.searchsorted(smallest[:searched], value, side="right")  # first front above
        result[s] = low + 1
        if first_only and low > 0:
            continue
        if low == n_fronts:
            n_fronts += 1
        smallest[low] = value
    return result
