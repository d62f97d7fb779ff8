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
MAX_THRESHOLDS = 8
# Depth-domain sums follow the thresholds (so the disparity columns keep their places):
# Σ|Z_E − Z_D|, Σ(Z_E − Z_D)², Σ|Z_E − Z_D|/Z_D and Σ(1/Z_E − 1/Z_D)².
FIELD_SUM_EZ = FIELD_BAD + MAX_THRESHOLDS
FIELD_SUM_EZ2 = FIELD_SUM_EZ + 1
FIELD_SUM_RELZ = FIELD_SUM_EZ + 2
FIELD_SUM_IZ2 = FIELD_SUM_EZ + 3
# Ground-truth-free sums (core/gtfree.py) follow: pixels in the view-prediction error and their
# Σ|I_L − I_R(x − d)|, pixels left-right checked and the inconsistent ones among them.
FIELD_N_VPE = FIELD_SUM_EZ + 4
FIELD_SUM_VPE = FIELD_N_VPE + 1
FIELD_N_LRC = FIELD_N_VPE + 2
FIELD_LRC = FIELD_N_VPE + 3
FIELD_COUNT = FIELD_N_VPE + 4


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy")
def _code_row(row: np.ndarray, lo: float, hi: float, out: np.ndarray) -> int:  # pragma: no cover
    """Copy one row with validity in the sign (missing → -0.0); the number of valid values."""
    count = 0
    for x in range(row.shape[0]):
        value = row[x]
        valid = (value > 0.0) & (value >= lo) & (value <= hi) & (value < np.inf)
        out[x] = value if valid else -0.0
        count += 1 if valid else 0
    return count


@njit(cache=True, nogil=True, inline="always")
def _all_valid8(row: np.ndarray, x: int) -> bool:  # pragma: no cover - compiled
    """Whether ``row[x:x+8]`` are all valid (one branch for eight values)."""
    return (
        (row[x] > 0.0)
        & (row[x + 1] > 0.0)
        & (row[x + 2] > 0.0)
        & (row[x + 3] > 0.0)
        & (row[x + 4] > 0.0)
        & (row[x + 5] > 0.0)
        & (row[x + 6] > 0.0)
        & (row[x + 7] > 0.0)
    )


@njit(cache=True, nogil=True)
def _fill_row_gaps(out: np.ndarray) -> None:  # pragma: no cover - compiled
    """KITTI background interpolation of one coded row that has at least one valid value."""
    width = out.shape[0]
    x = 0
    while True:
        while x + 8 <= width and _all_valid8(out, x):  # skip a run of valid values
            x += 8
        while x < width and out[x] > 0.0:
            x += 1
        if x == width:
            return
        gap_start = x
        while x < width and not out[x] > 0.0:
            x += 1
        if gap_start == 0:
            fill = out[x]  # leading gap: the first valid value
        elif x == width:
            fill = out[gap_start - 1]  # trailing gap: the last valid value
        else:
            fill = min(out[gap_start - 1], out[x])  # the farther neighbour
        out[gap_start:x] = -fill


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
        count = _code_row(est[y], lo, hi, out[y])
        if count == 0:
            continue
        if first_row < 0:
            first_row = y
        last_row = y
        if policy == POLICY_INTERPOLATE and count < width:
            _fill_row_gaps(out[y])
    if policy != POLICY_INTERPOLATE or first_row < 0:
        return
    for y in range(first_row):  # rows above the first row with any valid value copy it
        out[y, :] = -np.abs(out[first_row])
    for y in range(last_row + 1, height):  # rows below the last one likewise
        out[y, :] = -np.abs(out[last_row])


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy")
def gather_estimate(
    estimate: np.ndarray, order: np.ndarray, lo: float, hi: float, coded: bool, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """Gather the estimate at the evaluated pixels (partition order), validity in the sign.

    ``out[k] > 0``: a valid estimate. ``out[k] <= 0``: missing, to be scored as ``-out[k]``
    (the interpolated value when ``estimate`` was coded by :func:`normalise_estimate`,
    otherwise 0).
    """
    for k in range(order.shape[0]):  # a plain gather, then a contiguous pass: both vectorise
        out[k] = estimate[order[k]]
    for k in range(order.shape[0]):
        raw = out[k]
        valid = (raw > 0.0) & (raw >= lo) & (raw <= hi) & (raw < np.inf)
        out[k] = raw if valid else (raw if coded else -0.0)


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy")
def _cell_terms(
    values: np.ndarray,
    gt: np.ndarray,
    fb: float,
    depth_offset: float,
    mu: float,
    delta: float,
    missing_weight: float,
) -> tuple[
    float, float, float, float, float, float, float, float, float, float, float, float, float
]:  # pragma: no cover
    """Sums of one cell's terms; contiguous slices and no branches, so it vectorises.

    Depth terms use ``Z = f·B / max(d + doffs, μ)``: exact for every point with
    ``d + doffs ≥ μ``, and a missing estimate scored as 0 costs a large but finite depth.
    """
    doffs = depth_offset - mu
    n_valid = 0.0
    n_eval = 0.0
    sum_e = 0.0
    sum_e2 = 0.0
    sum_rel = 0.0
    sze = 0.0
    bmpre = 0.0
    d1 = 0.0
    bad = 0.0
    sum_ez = 0.0
    sum_ez2 = 0.0
    sum_relz = 0.0
    sum_iz2 = 0.0
    for k in range(values.shape[0]):
        raw = np.float64(values[k])
        weight = 1.0 if raw > 0.0 else missing_weight
        value = abs(raw)
        d = np.float64(gt[k])
        e = abs(value - d)
        rel = e / d
        n_valid += 1.0 if raw > 0.0 else 0.0
        n_eval += weight
        sum_e += weight * e
        sum_e2 += weight * e * e
        sum_rel += weight * rel
        sze += weight * fb * e / abs((d + depth_offset) * (value + depth_offset))
        bmpre += weight * rel if e > delta else 0.0
        d1 += weight if (e > 3.0 and e > 0.05 * d) else 0.0
        bad += weight if e > delta else 0.0
        inverse_d = max(d + doffs, mu)  # f·B / Z of the GT
        inverse_e = max(value + doffs, mu)
        ez = fb * abs(inverse_d - inverse_e) / (inverse_d * inverse_e)
        sum_ez += weight * ez
        sum_ez2 += weight * ez * ez
        sum_relz += weight * abs(inverse_d - inverse_e) / inverse_e  # |Z_E − Z_D| / Z_D
        iz = (inverse_e - inverse_d) / fb
        sum_iz2 += weight * iz * iz
    return (
        n_valid,
        n_eval,
        sum_e,
        sum_e2,
        sum_rel,
        sze,
        bmpre,
        d1,
        bad,
        sum_ez,
        sum_ez2,
        sum_relz,
        sum_iz2,
    )


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy")
def _bad_count(
    values: np.ndarray, gt: np.ndarray, threshold: float, missing_weight: float
) -> float:  # pragma: no cover - compiled
    """Weighted number of points of one cell with error above ``threshold``."""
    bad = 0.0
    for k in range(values.shape[0]):
        raw = np.float64(values[k])
        weight = 1.0 if raw > 0.0 else missing_weight
        bad += weight if abs(abs(raw) - np.float64(gt[k])) > threshold else 0.0
    return bad


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy")
def accumulate_cells(
    values: np.ndarray,
    offsets: np.ndarray,
    gt_sorted: np.ndarray,
    fb: float,
    depth_offset: float,
    mu: float,
    thresholds: np.ndarray,
    missing_weight: float,
    sums: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Accumulate every measure's terms per cell in one pass over the valid-GT points.

    ``values`` comes from :func:`gather_estimate` and ``gt_sorted`` holds ``D`` in the
    same (partition) order; ``offsets`` delimit the cells. ``depth_offset`` is
    ``doffs + μ``; the SZE term ``|f·B/(D+o) − f·B/(E+o)|`` is computed as the equal
    ``f·B·e / |(D+o)(E+o)|``, which has no cancellation; the depth-domain terms use ``μ`` only
    as a floor of ``d + doffs`` (see :func:`_cell_terms`). ``thresholds[0]`` is δ (bmp,
    bmpre), the others the bad-x thresholds (``inf`` entries are unused).
    ``missing_weight`` is 0 under the ``ignore`` policy (missing points leave the error
    measures) and 1 otherwise.
    """
    for cell in range(offsets.shape[0] - 1):
        start = offsets[cell]
        stop = offsets[cell + 1]
        cell_values = values[start:stop]
        cell_gt = gt_sorted[start:stop]
        terms = _cell_terms(
            cell_values, cell_gt, fb, depth_offset, mu, thresholds[0], missing_weight
        )
        row = sums[cell]
        row[FIELD_N] += stop - start
        row[FIELD_VALID] += terms[0]
        row[FIELD_EVAL] += terms[1]
        row[FIELD_SUM_E] += terms[2]
        row[FIELD_SUM_E2] += terms[3]
        row[FIELD_SUM_REL] += terms[4]
        row[FIELD_SZE] += terms[5]
        row[FIELD_BMPRE] += terms[6]
        row[FIELD_D1] += terms[7]
        row[FIELD_BAD] += terms[8]
        row[FIELD_SUM_EZ] += terms[9]
        row[FIELD_SUM_EZ2] += terms[10]
        row[FIELD_SUM_RELZ] += terms[11]
        row[FIELD_SUM_IZ2] += terms[12]
        for t in range(1, thresholds.shape[0]):
            if thresholds[t] < np.inf:
                row[FIELD_BAD + t] += _bad_count(
                    cell_values, cell_gt, thresholds[t], missing_weight
                )


@njit(cache=True, nogil=True)
def counting_order(
    cells: np.ndarray, n_cells: int
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover
    """Stable counting sort of pixel indices by cell (cell < 0: not evaluated)."""
    flat = cells.ravel()
    lanes = np.zeros((4, n_cells + 1), dtype=np.int64)  # interleaved: see histogram_moments
    for i in range(flat.shape[0]):
        c = flat[i]
        if c >= 0:
            lanes[i & 3, c + 1] += 1
    counts = lanes.sum(axis=0)
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
    targets = np.empty(width, dtype=np.int64)  # -1: not valid, -2: lands outside the image
    for y in range(height):
        zbuffer[:] = -np.inf
        for x in range(width):
            target = -1
            if valid[y, x]:
                d = gt[y, x]
                target = int(np.floor(x - d + 0.5))
                if 0 <= target < width:
                    zbuffer[target] = max(zbuffer[target], d)
                else:
                    target = -2
            targets[x] = target
        for x in range(width):
            target = targets[x]
            if target == -2 or (target >= 0 and zbuffer[target] > gt[y, x] + tolerance):
                occluded[y, x] = True
    return occluded


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy")
def kmeans_1d_pass(
    values: np.ndarray, valid: np.ndarray, low: float, high: float
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """One Lloyd step of 3-means on 1-D values: counts and sums of the three clusters.

    Cluster 0 holds values ``<= low``, 1 values in ``(low, high]``, 2 values ``> high``.
    """
    flat_values = values.ravel()
    flat_valid = valid.ravel()
    n0 = n1 = n2 = 0.0
    s0 = s1 = s2 = 0.0
    for i in range(flat_values.shape[0]):
        v = np.float64(flat_values[i]) if flat_valid[i] else 0.0
        w = 1.0 if flat_valid[i] else 0.0
        in0 = w if v <= low else 0.0
        in2 = w if v > high else 0.0
        in1 = w - in0 - in2
        n0 += in0
        n1 += in1
        n2 += in2
        s0 += in0 * v
        s1 += in1 * v
        s2 += in2 * v
    return np.array([n0, n1, n2]), np.array([s0, s1, s2])


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy")
def valid_range(values: np.ndarray, valid: np.ndarray) -> tuple[float, float]:  # pragma: no cover
    """Smallest and largest of the valid values."""
    flat_values = values.ravel()
    flat_valid = valid.ravel()
    lo = np.inf
    hi = -np.inf
    for i in range(flat_values.shape[0]):
        v = np.float64(flat_values[i])
        lo = min(lo, v) if flat_valid[i] else lo
        hi = max(hi, v) if flat_valid[i] else hi
    return lo, hi


@njit(cache=True, nogil=True)
def threshold_labels(values: np.ndarray, low: float, high: float) -> np.ndarray:  # pragma: no cover
    """Class 0 above ``high``, 1 in ``(low, high]``, 2 otherwise (near / mid / far)."""
    labels = np.empty(values.shape, dtype=np.int32)
    flat_values = values.ravel()
    flat_labels = labels.ravel()
    for i in range(flat_values.shape[0]):
        v = flat_values[i]
        flat_labels[i] = 0 if v > high else (1 if v > low else 2)
    return labels


@njit(cache=True, nogil=True)
def best_three_split(
    counts: np.ndarray, sums: np.ndarray, squares: np.ndarray
) -> tuple[int, int]:  # pragma: no cover - compiled
    """Optimal least-squares split of histogram bins into three runs ``[0,i) [i,j) [j,B)``.

    Exhaustive over every pair of cuts with prefix sums: the global optimum of 3-means when
    clusters may only change at bin edges (1-D optimal clusters are intervals).
    """
    bins = counts.shape[0]
    cw = np.zeros(bins + 1)
    cs = np.zeros(bins + 1)
    cq = np.zeros(bins + 1)
    for b in range(bins):
        cw[b + 1] = cw[b] + counts[b]
        cs[b + 1] = cs[b] + sums[b]
        cq[b + 1] = cq[b] + squares[b]
    best = np.inf
    best_i = 1
    best_j = 2
    for i in range(1, bins - 1):
        n0 = cw[i]
        sse0 = cq[i] - cs[i] * cs[i] / n0 if n0 > 0 else 0.0
        for j in range(i + 1, bins):
            n1 = cw[j] - n0
            n2 = cw[bins] - cw[j]
            s1 = cs[j] - cs[i]
            s2 = cs[bins] - cs[j]
            sse1 = (cq[j] - cq[i]) - s1 * s1 / n1 if n1 > 0 else 0.0
            sse2 = (cq[bins] - cq[j]) - s2 * s2 / n2 if n2 > 0 else 0.0
            total = sse0 + sse1 + sse2
            if total < best:
                best = total
                best_i = i
                best_j = j
    return best_i, best_j


@njit(cache=True, nogil=True)
def histogram_moments(
    values: np.ndarray, valid: np.ndarray, lo: float, hi: float, bins: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Counts, sums and sums of squares of the valid values in ``bins`` equal bins."""
    # Neighbouring pixels usually fall in the same bin: a run of one bin is summed in
    # registers and added once, instead of chaining every update through memory.
    counts = np.zeros(bins, dtype=np.float64)
    sums = np.zeros(bins, dtype=np.float64)
    squares = np.zeros(bins, dtype=np.float64)
    flat_values = values.ravel()
    flat_valid = valid.ravel()
    scale = bins / (hi - lo) if hi > lo else 0.0
    current = -1
    run_count = 0.0
    run_sum = 0.0
    run_squares = 0.0
    for i in range(flat_values.shape[0]):
        if flat_valid[i]:
            v = np.float64(flat_values[i])
            b = min(int((v - lo) * scale), bins - 1)
            if b != current:
                if current >= 0:
                    counts[current] += run_count
                    sums[current] += run_sum
                    squares[current] += run_squares
                current = b
                run_count = 0.0
                run_sum = 0.0
                run_squares = 0.0
            run_count += 1.0
            run_sum += v
            run_squares += v * v
    if current >= 0:
        counts[current] += run_count
        sums[current] += run_sum
        squares[current] += run_squares
    return counts, sums, squares


@njit(cache=True, nogil=True)
def jump_mask(gt: np.ndarray, valid: np.ndarray, gap: float) -> np.ndarray:  # pragma: no cover
    """1 at both ends of every 4-neighbour GT jump larger than ``gap`` between valid points."""
    height, width = gt.shape
    jumps = np.zeros((height, width), dtype=np.uint8)
    for y in range(height):
        for x in range(width):
            if not valid[y, x]:
                continue
            d = gt[y, x]
            if x + 1 < width and valid[y, x + 1] and abs(d - gt[y, x + 1]) > gap:
                jumps[y, x] = 1
                jumps[y, x + 1] = 1
            if y + 1 < height and valid[y + 1, x] and abs(d - gt[y + 1, x]) > gap:
                jumps[y, x] = 1
                jumps[y + 1, x] = 1
    return jumps


@njit(cache=True, nogil=True)
def sparse_jump_mask(
    gt: np.ndarray, valid: np.ndarray, gap: float, width: int
) -> np.ndarray:  # pragma: no cover - compiled
    """1 at every valid point with a valid point in its ``width``-square differing by > ``gap``.

    The definition of depth discontinuities for sparse GT (LiDAR), whose points rarely have
    valid 4-neighbours; the square is centred on the point (``width // 2`` each side).
    """
    height, columns = gt.shape
    half = max(width, 1) // 2
    jumps = np.zeros((height, columns), dtype=np.uint8)
    for y in range(height):
        for x in range(columns):
            if not valid[y, x]:
                continue
            d = gt[y, x]
            found = False
            for r in range(max(y - half, 0), min(y + half + 1, height)):
                for c in range(max(x - half, 0), min(x + half + 1, columns)):
                    if valid[r, c] and abs(gt[r, c] - d) > gap:
                        found = True
                        break
                if found:
                    break
            jumps[y, x] = 1 if found else 0
    return jumps


@njit(cache=True, nogil=True)
def add_labels(cells: np.ndarray, labels: np.ndarray, stride: int) -> None:  # pragma: no cover
    """``cells += labels · stride`` in place (one pass, no temporary)."""
    flat_cells = cells.ravel()
    flat_labels = labels.ravel()
    for i in range(flat_cells.shape[0]):
        flat_cells[i] += flat_labels[i] * stride


@njit(cache=True, nogil=True)
def clear_invalid(cells: np.ndarray, valid: np.ndarray, value: int) -> None:  # pragma: no cover
    """``cells[~valid] = value`` in place."""
    flat_cells = cells.ravel()
    flat_valid = valid.ravel()
    for i in range(flat_cells.shape[0]):
        if not flat_valid[i]:
            flat_cells[i] = value
