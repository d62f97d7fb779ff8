"""Compiled non-dominated sorting on integer ranks: no method × method table is ever built.

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
  otherwise members are compared with an early exit. Fast while fronts are small (correlated
  objectives); its comparisons grow with the fronts, so on random or weakly correlated
  objectives (most methods in a few huge fronts) it gives up early, by a projected budget,
  for a bitset sort: each method's dominators as one bit per method, ANDed objective by
  objective (as in Merge Non-Dominated Sorting, Moreno et al. 2018), a few cache-sized chunks
  of methods at a time, about ``(M − 1) N² / 128`` word operations (:func:`fronts_many`).

The compiled functions are only compiled when a model is first evaluated with more than
:data:`SMALL_PROBLEM` methods (numba compiles lazily and caches on disk); fewer methods, the
common case of a handful of stereo methods, use the dominance table directly and need no
compilation at all.
"""

from __future__ import annotations

import math

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

# The sum-order insertion gives up (returns ``[_OVER_BUDGET]``) when its projected work exceeds
# the budget; checked every _CHECK_EVERY rows once 1/_CHECK_AFTER of them are in.
_OVER_BUDGET = -2
_CHECK_EVERY = 64
_CHECK_AFTER = 32


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
) -> tuple[bool, int]:  # pragma: no cover - compiled
    """Whether a member of the front starting at ``first_block`` dominates ``row``.

    Every member precedes ``row`` in sum order, so ``t ≤ row`` everywhere with a smaller sum
    is dominance; oldest blocks first (the smallest sums, the likeliest dominators).
    Also returns how many blocks and members it looked at (the budget of :func:`fronts_by_sum`).
    """
    m = row.shape[0]
    b = first_block
    looked = 0
    while b >= 0:
        looked += 1
        possible = True
        for j in range(m):
            if row[j] < block_min[b, j]:  # better than every member of the block here
                possible = False
                break
        if possible:
            looked += block_size[b]
            for k in range(block_size[b]):
                if block_sums[b, k] < row_sum:  # an equal sum is an incomparable row
                    dominated = True
                    for j in range(m):
                        if block_rows[b, k, j] > row[j]:
                            dominated = False
                            break
                    if dominated:
                        return True, looked
        b = next_block[b]
    return False, looked


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


def fronts_by_sum(
    ranks: np.ndarray, first_only: bool, budget: float = math.inf
) -> np.ndarray | None:
    """Front number (1 = non-dominated) of every row of ``ranks`` (int32, rows × objectives).

    ``first_only`` stops at A*: every dominated row gets 2. Duplicate rows are sorted once.
    The sorts run in numpy (a sort compiled by numba costs seconds of JIT time). ``None`` when
    the comparisons, projected from the rows inserted so far, would exceed ``budget``.
    """
    n = ranks.shape[0]
    sums = ranks.sum(axis=1, dtype=np.int64)
    order = np.argsort(sums, kind="stable")
    hashes = np.full(n, 0xCBF29CE484222325, dtype=np.uint64)
    for column in ranks.T:  # FNV-1a over the ranks (wrapping uint64 arithmetic)
        hashes = (hashes ^ column.astype(np.uint64)) * np.uint64(0x100000001B3)
    twin = _twins(ranks, np.argsort(hashes, kind="stable"), hashes)
    capacity = n // _BLOCK + 64
    limit = min(budget, 2.0**62)  # numba wants a finite number
    while True:  # blocks needed: at most n / _BLOCK full ones plus one part-filled per front
        result = _insert_sorted(ranks, sums, order, twin, first_only, capacity, limit)
        if result[0] == _OVER_BUDGET:
            return None
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
    budget: float,
) -> np.ndarray:  # pragma: no cover - compiled
    """Fronts by inserting rows in ``order`` (ascending ``sums``).

    ``[-1]`` when out of blocks, ``[_OVER_BUDGET]`` when the work so far plus the remaining
    rows at the latest rate per row exceeds ``budget`` (checked every :data:`_CHECK_EVERY`
    rows once ``1/_CHECK_AFTER`` of them are in). On large fronts the rate keeps growing, so
    the projection is optimistic and an abandoned attempt has cost a fraction of the budget.
    """
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
    work = 0
    last_work = 0  # work at the previous check, _CHECK_EVERY rows ago
    for p in range(n):
        if p % _CHECK_EVERY == 0:
            rate = (work - last_work) / _CHECK_EVERY  # per row, lately
            if p * _CHECK_AFTER >= n and work + rate * (n - p) > budget:
                result[0] = _OVER_BUDGET
                return result
            last_work = work
        s = order[p]
        if twin[s] != s:
            continue
        row = ranks[s]
        low = 0
        high = min(n_fronts, 1) if first_only else n_fronts
        while low < high:  # dominated by front k ⇒ dominated by every front before k
            middle = (low + high) // 2
            dominated, looked = _dominated_by_front(
                row,
                sums[s],
                first_block[middle],
                block_rows,
                block_sums,
                block_min,
                block_size,
                next_block,
            )
            work += looked
            if dominated:
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


_ALL_BITS = np.uint64(0xFFFFFFFFFFFFFFFF)
_ONE = np.uint64(1)

# The bitset sort keeps the candidate dominators of this many 64-bit words of rows at a time
# (4 MB: in the last-level cache) and refuses (``None``) when its front sets would exceed
# _FRONT_WORDS (64 MB): then the sum-order insertion runs instead.
_CHUNK_WORDS = 1 << 19
_FRONT_WORDS = 1 << 23

# The sum-order insertion is kept while its projected comparisons (blocks and members looked
# at) times this stay within the bitset sort's word operations. Measured on the inputs of
# bench/bench_models.py at N = 10³ … 3·10⁴, M = 3 … 50: where the insertion was faster its
# comparisons were words / 1.4 … / 67 (correlated sweeps), where the bitsets were faster
# words / 0.3 … / 1.3 (random and weakly correlated); a sweep whose noise is a third of its
# spread (words / 2.5) stays with the insertion, 1.7× slower than the bitsets there.
WORDS_PER_COMPARISON = 1.5


def bitset_work(n: int, m: int) -> float:
    """Words the bitset sort ANDs at most: ``m − 1`` passes over a triangle of ``n² / 2`` bits."""
    return (m - 1) * n * n / 128.0


def fronts_many(ranks: np.ndarray, first_only: bool) -> np.ndarray:
    """Fronts of three or more objectives by whichever sort is cheaper on these rows.

    Sum-order insertion is fastest when fronts are small (correlated objectives: a dominator
    is found among few members); when fronts are huge (random or weakly correlated objectives:
    most rows in the first few fronts) its comparisons grow with the front, and the bitset
    sort's fixed ``(m − 1) n² / 128`` word operations win. The insertion runs first within
    that budget and gives up early when its extrapolated work exceeds it.
    """
    n, m = ranks.shape
    budget = bitset_work(n, m) / WORDS_PER_COMPARISON
    result = fronts_by_sum(ranks, first_only, budget)
    if result is None:
        result = fronts_bitset(ranks, first_only)
    if result is None:  # too many fronts for their bitsets
        result = fronts_by_sum(ranks, first_only)
    assert result is not None  # without a budget the insertion always finishes
    return result


def fronts_bitset(ranks: np.ndarray, first_only: bool) -> np.ndarray | None:
    """Front numbers from each row's set of dominators, one bit per row (bitset sort).

    Rows are ordered by (first objective, sum of ranks): a dominator is strictly earlier, and
    rows equal in both are identical or incomparable. A row's candidate set starts as every
    earlier row of a smaller key and is ANDed, per further objective, with the rows no worse
    there (Merge Non-Dominated Sorting, Moreno et al. 2018): what remains are exactly its
    dominators (duplicates never enter: they share the key). Its front is then one more than
    the last front its set meets (a binary search: meeting front k implies meeting every
    earlier one). ``None`` when the fronts' sets would exceed :data:`_FRONT_WORDS`.
    """
    n = ranks.shape[0]
    sums = ranks.sum(axis=1, dtype=np.int64)
    order = np.lexsort((sums, ranks[:, 0]))
    first, total = ranks[order, 0], sums[order]
    new_key = np.ones(n, dtype=np.bool_)
    new_key[1:] = (first[1:] != first[:-1]) | (total[1:] != total[:-1])
    key_start = np.maximum.accumulate(np.where(new_key, np.arange(n), 0))
    words = (n + 63) // 64
    chunk = max(64, _CHUNK_WORDS // words)
    max_fronts = max(1, _FRONT_WORDS // words)
    result = _bitset_fronts(ranks, order, key_start, first_only, chunk, max_fronts)
    return None if result[0] < 0 else result


@njit(cache=True, nogil=True)
def _by_objective(
    ranks: np.ndarray, order: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Per objective: positions in ``order`` sorted by that objective, and where ties start.

    Dense ranks lie in ``[0, n)``, so a counting sort per objective.
    """
    n, m = ranks.shape
    positions = np.empty((m, n), dtype=np.int64)
    run_starts = np.zeros((m, n), dtype=np.bool_)
    counts = np.empty(n + 1, dtype=np.int64)
    for j in range(m):
        counts[:] = 0
        for i in range(n):
            counts[ranks[i, j] + 1] += 1
        for k in range(n):
            counts[k + 1] += counts[k]
        for k in range(n):
            if counts[k + 1] > counts[k]:
                run_starts[j, counts[k]] = True
        for p in range(n):
            r = ranks[order[p], j]
            positions[j, counts[r]] = p
            counts[r] += 1
    return positions, run_starts


@njit(cache=True, nogil=True)
def _narrow(
    candidates: np.ndarray, allowed: np.ndarray, low: int, high: int
) -> tuple[int, int]:  # pragma: no cover - compiled
    """AND ``allowed`` into ``candidates[low:high]``; the range of words still non-zero."""
    for w in range(low, high):
        candidates[w] &= allowed[w]
    while low < high and candidates[low] == 0:
        low += 1
    while high > low and candidates[high - 1] == 0:
        high -= 1
    return low, high


@njit(cache=True, nogil=True)
def _meets(
    candidates: np.ndarray, members: np.ndarray, low: int, high: int
) -> bool:  # pragma: no cover - compiled
    """Whether the two bitsets share a row within words ``[low, high)``."""
    for w in range(low, high):  # noqa: SIM110 - an explicit loop: numba compiles no any(generator)
        if candidates[w] & members[w]:
            return True
    return False


@njit(cache=True, nogil=True)
def _bitset_fronts(
    ranks: np.ndarray,
    order: np.ndarray,
    key_start: np.ndarray,
    first_only: bool,
    chunk: int,
    max_fronts: int,
) -> np.ndarray:  # pragma: no cover - compiled
    """Fronts of the rows at positions ``order`` (see :func:`fronts_bitset`); ``[-1]`` if too many.

    Positions are handled ``chunk`` at a time: their candidate sets (words up to the chunk's
    end only) stay in cache while each objective is walked once in its sorted order, ANDing a
    row's set with the rows seen so far once its whole tie run has been seen.
    """
    n, m = ranks.shape
    words = (n + 63) // 64
    by_objective, run_starts = _by_objective(ranks, order)
    result = np.zeros(n, dtype=np.int64)
    seen = np.zeros(words, dtype=np.uint64)
    capacity = 16
    fronts = np.zeros((capacity, words), dtype=np.uint64)  # members of each front
    n_fronts = 0
    candidates = np.empty((chunk, words), dtype=np.uint64)
    low = np.empty(chunk, dtype=np.int64)  # non-zero words of each candidate set
    high = np.empty(chunk, dtype=np.int64)
    pending = np.empty(chunk, dtype=np.int64)
    for c0 in range(0, n, chunk):
        c1 = min(n, c0 + chunk)
        for k in range(c1 - c0):
            start = key_start[c0 + k]
            full = start // 64
            for w in range(full):
                candidates[k, w] = _ALL_BITS
            high[k] = full
            if start % 64:
                candidates[k, full] = (_ONE << np.uint64(start % 64)) - _ONE
                high[k] = full + 1
            low[k] = 0
        for j in range(1, m):
            column = by_objective[j]
            runs = run_starts[j]
            seen[: (c1 + 63) // 64] = 0
            n_pending = 0
            for t in range(n + 1):
                if t == n or runs[t]:  # the run before t is complete: narrow its rows
                    for a in range(n_pending):
                        k = pending[a]
                        if low[k] < high[k]:
                            low[k], high[k] = _narrow(candidates[k], seen, low[k], high[k])
                    n_pending = 0
                    if t == n:
                        break
                q = column[t]
                if q < c1:  # later rows are never candidates of this chunk
                    seen[q >> 6] |= _ONE << np.uint64(q & 63)
                    if q >= c0:
                        pending[n_pending] = q - c0
                        n_pending += 1
        for k in range(c1 - c0):
            p = c0 + k
            if low[k] >= high[k]:
                front = 0
            elif first_only:
                front = 1
            else:
                below = 1  # dominated, so at least front 1 (0-based)
                above = n_fronts
                while below < above:
                    middle = (below + above) // 2
                    if _meets(candidates[k], fronts[middle], low[k], high[k]):
                        below = middle + 1
                    else:
                        above = middle
                front = below
            result[order[p]] = front + 1
            if first_only:
                continue
            if front == n_fronts:
                if n_fronts == max_fronts:
                    result[0] = -1
                    return result
                if n_fronts == capacity:
                    grown = np.zeros((2 * capacity, words), dtype=np.uint64)
                    grown[:capacity] = fronts
                    fronts = grown
                    capacity *= 2
                n_fronts += 1
            fronts[front, p >> 6] |= _ONE << np.uint64(p & 63)
    return result
