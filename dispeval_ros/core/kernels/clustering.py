"""Three-class k-means of GT values (near / mid / far thresholds) over bins."""

from __future__ import annotations

import numpy as np

from dispeval_ros.core.kernels._jit import njit

#: Values per block of :func:`kmeans_three`'s bin ranges (a block is read whole or skipped).
KMEANS_BLOCK = 64


@njit(cache=True, nogil=True, error_model="numpy")
def kmeans_three(
    values: np.ndarray,
    valid: np.ndarray,
    lo: float,
    hi: float,
    max_iterations: int,
    counts: np.ndarray,
    moments: np.ndarray,
    window: np.ndarray,
    bin_of: np.ndarray,
    thresholds: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Deterministic 1-D 3-means of the ``valid`` ``values`` (in ``[lo, hi]``): two ``thresholds``.

    1. A histogram of ``bins`` equal bins with exact moments: each value's bin first
       (``bin_of``, a vectorised pass; the spare bin ``bins`` for a value not valid), then one
       pass in which a run of values in one bin is summed in registers.
    2. The global optimum over the histogram: every pair of cuts at bin edges, by prefix sums
       (1-D optimal clusters are intervals), gives the starting centroids.
    3. Lloyd steps until the centroids no longer change. Binning is monotonic, so a bin below
       the one holding a threshold lies wholly below it: whole bins add their moments, only
       the (at most two) bins holding a threshold are split value by value. Their values are
       copied out once, with two bins either side (the thresholds rarely move further); a
       threshold leaving them copies again. A value equal to a threshold goes to the lower
       cluster.

    One compiled function without allocations; the caller allocates ``counts`` int64 zeros
    ``(bins + 1)``, ``moments`` float64 ``(8, bins + 1)`` with zeros in its first two rows,
    ``window`` one float64 per valid value and ``bin_of`` one uint16 per value (bins < 2¹⁶).
    """
    bins = counts.shape[0] - 1
    n = values.shape[0]
    scale = bins / (hi - lo) if hi > lo else 0.0
    sums = moments[0]
    squares = moments[1]
    current = 0
    run_n = 0
    run_s = 0.0
    run_q = 0.0
    for k in range(n):  # unsigned indices: no wrap-around test, so the loop vectorises
        i = np.uint64(k)
        ok = valid[i]
        value = np.float64(values[i])
        b = min(int(((value if ok else lo) - lo) * scale), bins - 1)  # never of NaN or inf
        bin_of[i] = np.uint16(b) if ok else np.uint16(bins)
    for k in range(n):  # runs of one bin accumulate in registers (the spare bin's: unused)
        i = np.uint64(k)
        v = np.float64(values[i])
        b = int(bin_of[i])
        if b != current:
            counts[current] += run_n
            sums[current] += run_s
            squares[current] += run_q
            current = b
            run_n = 0
            run_s = 0.0
            run_q = 0.0
        run_n += 1
        run_s += v
        run_q += v * v
    counts[current] += run_n
    sums[current] += run_s
    squares[current] += run_q
    cw = moments[5]  # prefix sums over the occupied bins
    cs = moments[6]
    cq = moments[7]
    cw[0] = cs[0] = cq[0] = 0.0
    occupied = 0
    for b in range(bins):
        if counts[b] > 0:
            cw[occupied + 1] = cw[occupied] + counts[b]
            cs[occupied + 1] = cs[occupied] + sums[b]
            cq[occupied + 1] = cq[occupied] + squares[b]
            occupied += 1
    c0 = lo + (hi - lo) / 6
    c1 = lo + (hi - lo) / 2
    c2 = lo + 5 * (hi - lo) / 6
    if occupied >= 3:
        best = np.inf
        best_i = 1
        best_j = 2
        # Every error is >= 0 up to rounding (far below ``slack``): a first cluster that alone
        # costs more than the best pair found cannot lead to a better one.
        # Occupied bins make every cluster non-empty. The last cluster's error depends on the
        # second cut alone (computed once); the totals of one first cut are computed in a
        # vectorised loop, then scanned for the first smallest (row-major order, as before).
        slack = 1e-9 * abs(cq[occupied])
        last_error = moments[4]
        totals = moments[3]
        for j in range(2, occupied):
            s2 = cs[occupied] - cs[j]
            last_error[j] = (cq[occupied] - cq[j]) - s2 * s2 / (cw[occupied] - cw[j])
        for i in range(1, occupied - 1):
            n0 = cw[i]
            sse0 = cq[i] - cs[i] * cs[i] / n0
            if sse0 > best + slack:
                continue
            for j in range(i + 1, occupied):
                s1 = cs[j] - cs[i]
                totals[j] = sse0 + ((cq[j] - cq[i]) - s1 * s1 / (cw[j] - n0)) + last_error[j]
            for j in range(i + 1, occupied):
                if totals[j] < best:
                    best = totals[j]
                    best_i = i
                    best_j = j
        c0 = cs[best_i] / cw[best_i]
        c1 = (cs[best_j] - cs[best_i]) / (cw[best_j] - cw[best_i])
        c2 = (cs[occupied] - cs[best_j]) / (cw[occupied] - cw[best_j])
    starts = moments[2]  # where each copied bin's values start in ``window``
    fill = moments[3]
    first_low = last_low = first_high = last_high = -1  # the copied bins: two ranges
    for _ in range(max_iterations):
        low = (c0 + c1) / 2
        high = (c1 + c2) / 2
        cut_low = -1 if low < lo else (bins if low > hi else min(int((low - lo) * scale), bins - 1))
        cut_high = (
            -1 if high < lo else (bins if high > hi else min(int((high - lo) * scale), bins - 1))
        )
        if (0 <= cut_low < bins and not first_low <= cut_low <= last_low) or (
            0 <= cut_high < bins and not first_high <= cut_high <= last_high
        ):
            first_low = max(cut_low - 2, 0)
            last_low = min(cut_low + 2, bins - 1)
            first_high = max(cut_high - 2, 0)
            last_high = min(cut_high + 2, bins - 1)
            _copy_bins(
                values,
                counts,
                (first_low, last_low, first_high, last_high),
                bin_of,
                starts,
                fill,
                window,
            )
        n0 = n1 = n2 = 0.0
        s0 = s1 = s2 = 0.0
        for b in range(bins):
            if (b == cut_low) | (b == cut_high):
                for k in range(int(starts[b]), int(starts[b]) + counts[b]):
                    v = window[k]
                    if v <= low:
                        n0 += 1.0
                        s0 += v
                    elif v <= high:
                        n1 += 1.0
                        s1 += v
                    else:
                        n2 += 1.0
                        s2 += v
            elif b < cut_low:
                n0 += counts[b]
                s0 += sums[b]
            elif b < cut_high:
                n1 += counts[b]
                s1 += sums[b]
            else:
                n2 += counts[b]
                s2 += sums[b]
        u0 = s0 / n0 if n0 > 0 else c0
        u1 = s1 / n1 if n1 > 0 else c1
        u2 = s2 / n2 if n2 > 0 else c2
        if u0 == c0 and u1 == c1 and u2 == c2:
            break
        c0, c1, c2 = u0, u1, u2
    thresholds[0] = (c0 + c1) / 2
    thresholds[1] = (c1 + c2) / 2


@njit(cache=True, nogil=True, error_model="numpy")
def _copy_bins(
    values: np.ndarray,
    counts: np.ndarray,
    ranges: tuple[int, int, int, int],
    bin_of: np.ndarray,
    starts: np.ndarray,
    fill: np.ndarray,
    window: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Copy the values of the bins in ``ranges`` (two inclusive bin ranges) to ``window``.

    Grouped by bin (``starts[b]``), in the order of ``values``. Blocks of
    :data:`KMEANS_BLOCK` values without one in those bins (``bin_of``: each value's bin) are
    skipped after a vectorised test.
    """
    bins = counts.shape[0] - 1
    first_low, last_low, first_high, last_high = ranges
    position = 0
    for b in range(bins):
        starts[b] = position
        fill[b] = position
        inside = (first_low <= b <= last_low) | (first_high <= b <= last_high)
        position += counts[b] if inside else 0
    low_from = np.uint16(first_low)  # b in [first, last] ⇔ (uint16) (b − first) <= last − first
    low_span = np.uint16(last_low - first_low)
    high_from = np.uint16(first_high)
    high_span = np.uint16(last_high - first_high)
    n = values.shape[0]
    for start in range(0, n, KMEANS_BLOCK):
        hit = np.uint16(0)
        if start + KMEANS_BLOCK <= n:  # a fixed count and unsigned indices: vectorised
            base = np.uint64(start)
            for j in range(KMEANS_BLOCK):
                b = bin_of[base + np.uint64(j)]
                hit |= np.uint16(np.uint16(b - low_from) <= low_span)
                hit |= np.uint16(np.uint16(b - high_from) <= high_span)
        else:
            hit = np.uint16(1)
        if hit == 0:
            continue
        for k in range(start, min(start + KMEANS_BLOCK, n)):
            b = int(bin_of[k])
            if (first_low <= b <= last_low) | (first_high <= b <= last_high):
                window[int(fill[b])] = values[k]
                fill[b] += 1
