"""Compiled per-pixel loops: the only place where the engine touches every pixel.

Everything here is numba-compiled (cached on disk) and works on plain arrays. The scoring
path is two passes per method: :func:`normalise_estimate` (validity + the missing-estimate
policy, row by row) and :func:`accumulate_cells` (one fused pass over the valid-GT pixels in
partition order, summing every measure's terms per cell). GT-side terms are prepared once
per ground-truth map by the partition.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# Floating-point flags that allow reassociation (vectorised reductions) but keep NaN/inf
# semantics, so a stray non-finite value can never be optimised into a wrong comparison.
_FAST = {"reassoc", "contract", "nsz", "arcp"}

POLICY_INTERPOLATE = 0
POLICY_THESIS = 1
POLICY_IGNORE = 2

# Column layout of the per-cell accumulator (float64); thresholds follow at FIELD_BAD.
FIELD_N = 0
FIELD_VALID = 1
FIELD_EVAL = 2
FIELD_SUM_E = 3
FIELD_SUM_E2 = 4
FIELD_SUM_REL = 5
FIELD_SZE = 6
FIELD_BMPRE = 7
FIELD_D1 = 8
FIELD_BAD = 9


@njit(cache=True, nogil=True)
def normalise_estimate(
    est: np.ndarray, lo: float, hi: float, policy: int, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """Write the estimate to ``out`` with validity in the sign bit.

    ``out > 0``: a valid estimate, its value. ``out <= 0``: missing; ``-out`` is the value
    to score (KITTI background interpolation under ``interpolate``, 0 otherwise). Valid means
    finite, > 0 and within ``[lo, hi]``.
    """
    height, width = est.shape
    first_row = -1
    last_row = -1
    for y in range(height):
        row = est[y]
        orow = out[y]
        previous = -1  # column of the last valid estimate in this row
        for x in range(width):
            value = row[x]
            if value > 0.0 and value >= lo and value <= hi and value < np.inf:
                orow[x] = value
                if policy == POLICY_INTERPOLATE:
                    if previous < 0:
                        for k in range(x):  # leading gap: the first valid value
                            orow[k] = -value
                    elif previous < x - 1:
                        fill = min(orow[previous], value)  # the farther neighbour
                        for k in range(previous + 1, x):
                            orow[k] = -fill
                previous = x
            else:
                orow[x] = -0.0
        if previous >= 0:
            if policy == POLICY_INTERPOLATE:
                fill = orow[previous]
                for k in range(previous + 1, width):  # trailing gap: the last valid value
                    orow[k] = -fill
            if first_row < 0:
                first_row = y
            last_row = y
    if policy == POLICY_INTERPOLATE and first_row >= 0:
        for y in range(first_row):  # rows above the first row with any valid value
            for x in range(width):
                value = out[first_row, x]
                out[y, x] = -value if value > 0.0 else value
        for y in range(last_row + 1, height):
            for x in range(width):
                value = out[last_row, x]
                out[y, x] = -value if value > 0.0 else value


MAX_THRESHOLDS = 8
_CHUNK = 2048


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy")
def accumulate_cells(
    work: np.ndarray,
    order: np.ndarray,
    offsets: np.ndarray,
    gt_sorted: np.ndarray,
    inv_gt_sorted: np.ndarray,
    depth_gt_sorted: np.ndarray,
    fb: float,
    depth_offset: float,
    thresholds: np.ndarray,
    skip_missing: bool,
    sums: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Accumulate every measure's terms per cell in one pass over the valid-GT pixels.

    ``work`` is a normalised estimate (flat view), ``order`` the pixel indices grouped by
    cell (``offsets`` delimit the cells), ``*_sorted`` GT-side terms in the same order:
    ``D``, ``1/D`` and ``f·B/(D + doffs + μ)``. ``depth_offset`` is ``doffs + μ``.
    ``thresholds`` has ``MAX_THRESHOLDS`` entries: δ (bmp, bmpre) first, then the bad-x
    thresholds, padded with ``inf``. The loop body is branch-free so it vectorises.
    """
    t0, t1, t2, t3 = thresholds[0], thresholds[1], thresholds[2], thresholds[3]
    t4, t5, t6, t7 = thresholds[4], thresholds[5], thresholds[6], thresholds[7]
    buffer = np.empty(_CHUNK, dtype=np.float64)
    for cell in range(offsets.shape[0] - 1):
        start = offsets[cell]
        stop = offsets[cell + 1]
        n_valid = 0.0
        n_eval = 0.0
        sum_e = 0.0
        sum_e2 = 0.0
        sum_rel = 0.0
        sze = 0.0
        bmpre = 0.0
        d1 = 0.0
        b0 = b1 = b2 = b3 = b4 = b5 = b6 = b7 = 0.0
        for chunk in range(start, stop, _CHUNK):
            size = min(_CHUNK, stop - chunk)
            for i in range(size):  # gather: the only non-contiguous access
                buffer[i] = work[order[chunk + i]]
            for i in range(size):  # contiguous and branch-free: vectorised by LLVM
                k = chunk + i
                raw = buffer[i]
                valid = 1.0 if raw > 0.0 else 0.0
                weight = 1.0 if (raw > 0.0 or not skip_missing) else 0.0
                value = abs(raw)
                d = np.float64(gt_sorted[k])
                e = abs(value - d)
                rel = e * np.float64(inv_gt_sorted[k])
                n_valid += valid
                n_eval += weight
                sum_e += weight * e
                sum_e2 += weight * e * e
                sum_rel += weight * rel
                sze += weight * abs(depth_gt_sorted[k] - fb / (value + depth_offset))
                bmpre += weight * rel if e > t0 else 0.0
                d1 += weight if (e > 3.0 and e > 0.05 * d) else 0.0
                b0 += weight if e > t0 else 0.0
                b1 += weight if e > t1 else 0.0
                b2 += weight if e > t2 else 0.0
                b3 += weight if e > t3 else 0.0
                b4 += weight if e > t4 else 0.0
                b5 += weight if e > t5 else 0.0
                b6 += weight if e > t6 else 0.0
                b7 += weight if e > t7 else 0.0
        row = sums[cell]
        row[FIELD_N] += stop - start
        row[FIELD_VALID] += n_valid
        row[FIELD_EVAL] += n_eval
        row[FIELD_SUM_E] += sum_e
        row[FIELD_SUM_E2] += sum_e2
        row[FIELD_SUM_REL] += sum_rel
        row[FIELD_SZE] += sze
        row[FIELD_BMPRE] += bmpre
        row[FIELD_D1] += d1
        row[FIELD_BAD + 0] += b0
        row[FIELD_BAD + 1] += b1
        row[FIELD_BAD + 2] += b2
        row[FIELD_BAD + 3] += b3
        row[FIELD_BAD + 4] += b4
        row[FIELD_BAD + 5] += b5
        row[FIELD_BAD + 6] += b6
        row[FIELD_BAD + 7] += b7


@njit(cache=True, nogil=True)
def counting_order(
    cells: np.ndarray, n_cells: int
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover
    """Stable counting sort of pixel indices by cell (cell < 0: not evaluated)."""
    flat = cells.ravel()
    counts = np.zeros(n_cells + 1, dtype=np.int64)
    for i in range(flat.shape[0]):
        c = flat[i]
        if c >= 0:
            counts[c + 1] += 1
    for c in range(n_cells):
        counts[c + 1] += counts[c]
    offsets = counts.copy()
    order = np.empty(counts[n_cells], dtype=np.int32)
    position = counts[:n_cells].copy()
    for i in range(flat.shape[0]):
        c = flat[i]
        if c >= 0:
            order[position[c]] = i
            position[c] += 1
    return order, offsets


@njit(cache=True, nogil=True)
def forward_warp_occlusion(
    gt: np.ndarray, valid: np.ndarray, tolerance: float
) -> np.ndarray:  # pragma: no cover - compiled
    """Occlusion of the left view from the left GT alone (z-buffer forward warping).

    Each valid point ``(x, y)`` lands at ``round(x − d)`` in the right view. It is occluded
    when it lands outside the image, or another point lands on the same position with a
    disparity larger by more than ``tolerance`` (that point is nearer and hides it).
    """
    height, width = gt.shape
    occluded = np.zeros((height, width), dtype=np.bool_)
    zbuffer = np.empty(width, dtype=np.float64)
    for y in range(height):
        zbuffer[:] = -np.inf
        for x in range(width):
            if valid[y, x]:
                target = int(np.floor(x - gt[y, x] + 0.5))
                if 0 <= target < width and gt[y, x] > zbuffer[target]:
                    zbuffer[target] = gt[y, x]
        for x in range(width):
            if valid[y, x]:
                target = int(np.floor(x - gt[y, x] + 0.5))
                if target < 0 or target >= width or zbuffer[target] > gt[y, x] + tolerance:
                    occluded[y, x] = True
    return occluded


@njit(cache=True, nogil=True)
def kmeans_1d_pass(
    values: np.ndarray, valid: np.ndarray, low: float, high: float
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """One Lloyd step of 3-means on 1-D values: counts and sums of the three clusters.

    Cluster 0 holds values ``<= low``, 1 values in ``(low, high]``, 2 values ``> high``.
    """
    counts = np.zeros(3, dtype=np.float64)
    sums = np.zeros(3, dtype=np.float64)
    flat_values = values.ravel()
    flat_valid = valid.ravel()
    for i in range(flat_values.shape[0]):
        if flat_valid[i]:
            v = np.float64(flat_values[i])
            c = 0 if v <= low else (1 if v <= high else 2)
            counts[c] += 1.0
            sums[c] += v
    return counts, sums


@njit(cache=True, nogil=True)
def histogram_sums(
    values: np.ndarray, valid: np.ndarray, lo: float, hi: float, bins: int
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Counts and exact value sums of the valid values in ``bins`` equal bins over [lo, hi]."""
    counts = np.zeros(bins, dtype=np.float64)
    sums = np.zeros(bins, dtype=np.float64)
    flat_values = values.ravel()
    flat_valid = valid.ravel()
    scale = bins / (hi - lo) if hi > lo else 0.0
    for i in range(flat_values.shape[0]):
        if flat_valid[i]:
            v = np.float64(flat_values[i])
            b = min(int((v - lo) * scale), bins - 1)
            counts[b] += 1.0
            sums[b] += v
    return counts, sums
