"""Compiled non-dominated sorting on integer ranks: no method × method matrix is ever built.

Every objective is first replaced by its dense rank (equal values share a rank, NaN is already
``+inf``, ``-0.0`` equals ``0.0``), so dominance is exact integer comparison and ties, duplicate
rows and signed zeros need no special case. Methods are then inserted one at a time into the
fronts found so far, in an order where a dominator always comes first:

* two objectives: lexicographic order, where the fronts' smallest second objective increases
  with the front index, so each method's front is a binary search (``O(N log N)``);
* more: ascending sum of ranks (a dominator has a strictly smaller sum), and the method's front
  is found by binary search over the fronts (ENS-BS, Zhang et al. 2015): a front is skipped at
  once when the method is better than every member on some objective (the front's per-objective
  minimum), otherwise its members are compared with an early exit.

The compiled functions are only compiled when a model is first evaluated (numba compiles
lazily and caches on disk).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _dominated_by_front(
    ranks: np.ndarray,
    sums: np.ndarray,
    s: int,
    front: int,
    front_min: np.ndarray,
    first: np.ndarray,
    following: np.ndarray,
) -> bool:  # pragma: no cover - compiled
    """Whether a member of ``front`` dominates method ``s`` (members all precede ``s``)."""
    m = ranks.shape[1]
    for j in range(m):  # better than every member on objective j: nobody dominates
        if ranks[s, j] < front_min[front, j]:
            return False
    t = first[front]
    while t >= 0:  # oldest member first: the smallest sums, the likeliest dominators
        if sums[t] < sums[s]:  # equal sums: equal rows or incomparable
            dominated = True
            for j in range(m):
                if ranks[t, j] > ranks[s, j]:
                    dominated = False
                    break
            if dominated:
                return True
        t = following[t]
    return False


@njit(cache=True, nogil=True)
def fronts_by_sum(ranks: np.ndarray, first_only: bool) -> np.ndarray:  # pragma: no cover
    """Front number (1 = non-dominated) of every row of ``ranks`` (int32, rows × objectives).

    ``first_only`` stops at A*: every dominated row gets 2.
    """
    n, m = ranks.shape
    sums = np.zeros(n, dtype=np.int64)
    for i in range(n):
        total = 0
        for j in range(m):
            total += ranks[i, j]
        sums[i] = total
    order = np.argsort(sums, kind="mergesort")
    result = np.zeros(n, dtype=np.int64)
    first = np.full(n, -1, dtype=np.int64)  # oldest member of each front
    last = np.full(n, -1, dtype=np.int64)  # newest member of each front
    following = np.full(n, -1, dtype=np.int64)  # the member added next, per row
    front_min = np.empty((n, m), dtype=ranks.dtype)
    n_fronts = 0
    for p in range(n):
        s = order[p]
        low = 0
        high = min(n_fronts, 1) if first_only else n_fronts
        while low < high:  # dominated by front k ⇒ dominated by every front before k
            middle = (low + high) // 2
            if _dominated_by_front(ranks, sums, s, middle, front_min, first, following):
                low = middle + 1
            else:
                high = middle
        result[s] = low + 1
        if first_only and low > 0:
            continue
        if low == n_fronts:
            n_fronts += 1
            first[low] = s
            for j in range(m):
                front_min[low, j] = ranks[s, j]
        else:
            following[last[low]] = s
            for j in range(m):
                front_min[low, j] = min(front_min[low, j], ranks[s, j])
        last[low] = s
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
    order = _counting_order(first, _counting_order(second, np.arange(n)))
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
        low = 0
        high = min(n_fronts, 1) if first_only else n_fronts
        while low < high:
            middle = (low + high) // 2
            if smallest[middle] <= value:
                low = middle + 1
            else:
                high = middle
        result[s] = low + 1
        if first_only and low > 0:
            continue
        if low == n_fronts:
            n_fronts += 1
        smallest[low] = value
    return result
