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

from dispeval_ros.jitcache import ensure_cache_location

ensure_cache_location()  # before any kernel is decorated with cache=True

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
        for k in range(gap_start, x):  # a loop, not a slice assignment: much less to compile
            out[k] = -fill


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
    for y in range(height):  # rows above the first row with any valid value copy it,
        source = first_row if y < first_row else last_row  # rows below the last one likewise
        if first_row <= y <= last_row:
            continue
        for x in range(width):
            out[y, x] = -abs(out[source, x])


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


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy", inline="always")
def _disparity_terms(
    raw: float, d: float, fb: float, depth_offset: float, delta: float, missing_weight: float
) -> tuple[float, float, float, float, float, float, float, float, float]:  # pragma: no cover
    """One point's disparity-domain terms (weight, valid, e, e², rel, SZE, BMPRE, D1, bad)."""
    weight = 1.0 if raw > 0.0 else missing_weight
    value = abs(raw)
    e = abs(value - d)
    rel = e / d
    return (
        weight,
        1.0 if raw > 0.0 else 0.0,
        weight * e,
        weight * e * e,
        weight * rel,
        weight * fb * e / abs((d + depth_offset) * (value + depth_offset)),
        weight * rel if e > delta else 0.0,
        weight if (e > 3.0 and e > 0.05 * d) else 0.0,
        weight if e > delta else 0.0,
    )


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy")
def _cell_terms(
    values: np.ndarray,
    gt: np.ndarray,
    fb: float,
    depth_offset: float,
    mu: float,
    delta: float,
    missing_weight: float,
    depth_terms: bool,
) -> tuple[
    float, float, float, float, float, float, float, float, float, float, float, float, float
]:  # pragma: no cover
    """Sums of one cell's terms; contiguous slices and no branches, so it vectorises.

    Depth terms use ``Z = f·B / max(d + doffs, μ)``: exact for every point with
    ``d + doffs ≥ μ``, and a missing estimate scored as 0 costs a large but finite depth.
    They cost as much as all the others together (two more divisions per point), so they
    are summed only when ``depth_terms`` (a depth-domain measure was asked for) and are 0
    otherwise; the loop is chosen once per cell, not per point.
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
    if depth_terms:
        for k in range(values.shape[0]):
            raw = np.float64(values[k])
            d = np.float64(gt[k])
            terms = _disparity_terms(raw, d, fb, depth_offset, delta, missing_weight)
            n_eval += terms[0]
            n_valid += terms[1]
            sum_e += terms[2]
            sum_e2 += terms[3]
            sum_rel += terms[4]
            sze += terms[5]
            bmpre += terms[6]
            d1 += terms[7]
            bad += terms[8]
            inverse_d = max(d + doffs, mu)  # f·B / Z of the GT
            inverse_e = max(abs(raw) + doffs, mu)
            ez = fb * abs(inverse_d - inverse_e) / (inverse_d * inverse_e)
            sum_ez += terms[0] * ez
            sum_ez2 += terms[0] * ez * ez
            sum_relz += terms[0] * abs(inverse_d - inverse_e) / inverse_e  # |Z_E − Z_D| / Z_D
            iz = (inverse_e - inverse_d) / fb
            sum_iz2 += terms[0] * iz * iz
    else:
        for k in range(values.shape[0]):
            terms = _disparity_terms(
                np.float64(values[k]), np.float64(gt[k]), fb, depth_offset, delta, missing_weight
            )
            n_eval += terms[0]
            n_valid += terms[1]
            sum_e += terms[2]
            sum_e2 += terms[3]
            sum_rel += terms[4]
            sze += terms[5]
            bmpre += terms[6]
            d1 += terms[7]
            bad += terms[8]
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
    depth_terms: bool,
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
    measures) and 1 otherwise. The depth-domain columns are summed only when
    ``depth_terms`` (otherwise they stay 0; measures are derived from requested fields only).
    """
    for cell in range(offsets.shape[0] - 1):
        start = offsets[cell]
        stop = offsets[cell + 1]
        cell_values = values[start:stop]
        cell_gt = gt_sorted[start:stop]
        terms = _cell_terms(
            cell_values, cell_gt, fb, depth_offset, mu, thresholds[0], missing_weight, depth_terms
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
    flat: np.ndarray,
    flat_valid: np.ndarray,
    lanes: np.ndarray,
    offsets: np.ndarray,
    order: np.ndarray,
) -> None:  # pragma: no cover
    """Mark invalid pixels ``-1`` in the flat cell image (in place), then sort pixels by cell.

    A stable counting sort: ``order[offsets[c]:offsets[c + 1]]`` are cell ``c``'s pixels.
    The caller allocates (kernels that allocate and return arrays take twice as long to
    compile): ``lanes`` zeros ``(4, cells + 1)``, ``offsets`` ``(cells + 1)``, ``order`` one
    entry per valid pixel.
    """
    n_cells = offsets.shape[0] - 1
    for i in range(flat.shape[0]):
        c = flat[i] if flat_valid[i] else -1
        flat[i] = c
        lanes[i & 3, c + 1] += 1  # interleaved counters: no chained increments
    offsets[0] = 0
    for c in range(n_cells):
        offsets[c + 1] = offsets[c] + lanes[0, c + 1] + lanes[1, c + 1] + lanes[2, c + 1]
        offsets[c + 1] += lanes[3, c + 1]
    for c in range(n_cells + 1):
        lanes[0, c] = offsets[c]  # from here on: where each cell's next pixel goes
    current = 0
    position = lanes[0, 0]
    for i in range(flat.shape[0]):  # a run of one cell is placed from a register
        c = flat[i]
        if c >= 0:
            if c != current:
                lanes[0, current] = position
                current = c
                position = lanes[0, c]
            order[position] = i
            position += 1


@njit(cache=True, nogil=True)
def forward_warp_occlusion(
    gt: np.ndarray,
    valid: np.ndarray,
    tolerance: float,
    occluded: np.ndarray,
    zbuffer: np.ndarray,
    targets: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Occlusion of the left view from the left GT alone (z-buffer forward warping).

    Each valid point ``(x, y)`` lands at ``round(x − d)`` in the right view. It is occluded
    when it lands outside the image, or another point lands on the same position with a
    disparity larger by more than ``tolerance`` (that point is nearer and hides it). Writes
    ``occluded`` (all False on entry); ``zbuffer`` (float64) and ``targets`` (int64) are
    one-row scratch arrays.
    """
    height, width = gt.shape
    for y in range(height):
        for x in range(width):
            zbuffer[x] = -np.inf
        for x in range(width):
            target = -1  # -1: not valid, -2: lands outside the image
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


@njit(cache=True, nogil=True)
def threshold_labels(
    flat_values: np.ndarray, low: float, high: float, flat_labels: np.ndarray
) -> None:  # pragma: no cover
    """Class 0 above ``high``, 1 in ``(low, high]``, 2 otherwise (near / mid / far)."""
    for i in range(flat_values.shape[0]):
        v = flat_values[i]
        flat_labels[i] = 0 if v > high else (1 if v > low else 2)


@njit(cache=True, nogil=True)
def kmeans_three(
    flat_values: np.ndarray,
    flat_valid: np.ndarray,
    max_iterations: int,
    packed: np.ndarray,
    bin_of: np.ndarray,
    binned: np.ndarray,
    lanes: np.ndarray,
    moments: np.ndarray,
    thresholds: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Deterministic 1-D 3-means of the valid values: writes the two ``thresholds``.

    1. Range and a histogram of ``bins`` equal bins with exact moments; the valid values are
       also grouped by bin. One pass over every pixel (branch-free: valid values are packed
       and the range taken together); the rest runs over the valid values only.
    2. The global optimum over the histogram: every pair of cuts at bin edges, by prefix sums
       (1-D optimal clusters are intervals), gives the starting centroids.
    3. Lloyd steps until the centroids no longer change. Binning is monotonic, so a bin below
       the one holding a threshold lies wholly below it: whole bins add their moments, only
       the (at most two) bins holding a threshold are split value by value. A value equal
       to a threshold goes to the lower cluster.

    One compiled function without allocations (each compiled kernel, and every array it
    allocates or returns, adds to the first run's compile time). The caller allocates:
    ``packed``, ``bin_of`` (int32), ``binned`` one entry per pixel; ``lanes`` int64 zeros
    ``(4, bins + 1)``; ``moments`` ``(7, bins + 1)`` float64.
    """
    bins = lanes.shape[1] - 1
    n = flat_values.shape[0]
    count = 0
    lo = np.inf
    hi = -np.inf
    for i in range(n):
        ok = flat_valid[i]
        v = np.float64(flat_values[i])
        packed[count] = v  # overwritten by the next value unless this one is valid
        count += 1 if ok else 0
        lo = min(lo, v if ok else np.inf)
        hi = max(hi, v if ok else -np.inf)
    scale = bins / (hi - lo) if hi > lo else 0.0
    for k in range(count):
        b = min(int((packed[k] - lo) * scale), bins - 1)
        bin_of[k] = b
        lanes[k & 3, b] += 1  # interleaved counters: no chained increments
    starts = lanes[1]  # lanes 1.. are free once the counts are summed into lane 0
    for b in range(bins):
        lanes[0, b] += lanes[1, b] + lanes[2, b] + lanes[3, b]
    starts[0] = 0
    for b in range(bins):
        starts[b + 1] = starts[b] + lanes[0, b]
    filled = lanes[2]
    for b in range(bins + 1):
        filled[b] = starts[b]
    current = 0
    position = filled[0]
    for k in range(count):  # a run of one bin is placed from a register
        b = bin_of[k]
        if b != current:
            filled[current] = position
            current = b
            position = filled[b]
        binned[position] = packed[k]
        position += 1
    sums = moments[0]  # per bin, in pixel order
    kept_counts = moments[1]  # occupied bins only, then their prefix sums
    kept_sums = moments[2]
    kept_squares = moments[3]
    occupied = 0
    for b in range(bins):
        total = 0.0
        total_squares = 0.0
        for k in range(starts[b], starts[b + 1]):
            v = binned[k]
            total += v
            total_squares += v * v
        sums[b] = total
        if starts[b + 1] > starts[b]:
            kept_counts[occupied] = starts[b + 1] - starts[b]
            kept_sums[occupied] = total
            kept_squares[occupied] = total_squares
            occupied += 1
    c0 = lo + (hi - lo) / 6
    c1 = lo + (hi - lo) / 2
    c2 = lo + 5 * (hi - lo) / 6
    if occupied >= 3:
        cw = moments[4]
        cs = moments[5]
        cq = moments[6]
        cw[0] = cs[0] = cq[0] = 0.0
        for b in range(occupied):
            cw[b + 1] = cw[b] + kept_counts[b]
            cs[b + 1] = cs[b] + kept_sums[b]
            cq[b + 1] = cq[b] + kept_squares[b]
        best = np.inf
        best_i = 1
        best_j = 2
        for i in range(1, occupied - 1):
            n0 = cw[i]
            sse0 = cq[i] - cs[i] * cs[i] / n0 if n0 > 0 else 0.0
            for j in range(i + 1, occupied):
                n1 = cw[j] - n0
                n2 = cw[occupied] - cw[j]
                s1 = cs[j] - cs[i]
                s2 = cs[occupied] - cs[j]
                sse1 = (cq[j] - cq[i]) - s1 * s1 / n1 if n1 > 0 else 0.0
                sse2 = (cq[occupied] - cq[j]) - s2 * s2 / n2 if n2 > 0 else 0.0
                total = sse0 + sse1 + sse2
                if total < best:
                    best = total
                    best_i = i
                    best_j = j
        c0 = cs[best_i] / cw[best_i]
        c1 = (cs[best_j] - cs[best_i]) / (cw[best_j] - cw[best_i])
        c2 = (cs[occupied] - cs[best_j]) / (cw[occupied] - cw[best_j])
    for _ in range(max_iterations):
        low = (c0 + c1) / 2
        high = (c1 + c2) / 2
        cut_low = -1 if low < lo else (bins if low > hi else min(int((low - lo) * scale), bins - 1))
        cut_high = (
            -1 if high < lo else (bins if high > hi else min(int((high - lo) * scale), bins - 1))
        )
        n0 = n1 = n2 = 0.0
        s0 = s1 = s2 = 0.0
        for b in range(bins):
            if (b == cut_low) | (b == cut_high):
                for k in range(starts[b], starts[b + 1]):
                    v = binned[k]
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
                n0 += starts[b + 1] - starts[b]
                s0 += sums[b]
            elif b < cut_high:
                n1 += starts[b + 1] - starts[b]
                s1 += sums[b]
            else:
                n2 += starts[b + 1] - starts[b]
                s2 += sums[b]
        u0 = s0 / n0 if n0 > 0 else c0
        u1 = s1 / n1 if n1 > 0 else c1
        u2 = s2 / n2 if n2 > 0 else c2
        if u0 == c0 and u1 == c1 and u2 == c2:
            break
        c0, c1, c2 = u0, u1, u2
    thresholds[0] = (c0 + c1) / 2
    thresholds[1] = (c1 + c2) / 2


@njit(cache=True, nogil=True)
def left_right_occlusion(
    gt: np.ndarray, gt_right: np.ndarray, valid: np.ndarray
) -> np.ndarray:  # pragma: no cover - compiled
    """Left-right check against the right-view GT, as MiddEval3's ``computemask`` does it.

    A valid point ``(x, y)`` is occluded when ``t = round(x − d)`` (C ``round``: halves away
    from zero, so −0.5 → −1) is outside the image, the right GT at ``(t, y)`` is unknown
    (not finite or ``<= 0``), or ``|d − D_R(t, y)| > 1``.
    """
    height, width = gt.shape
    occluded = np.empty((height, width), dtype=np.bool_)
    for y in range(height):
        for x in range(width):  # branch-free: every pixel does the same work
            ok = valid[y, x]
            d = np.float64(gt[y, x]) if ok else 0.0
            shift = x - d
            rounded = int(np.floor(abs(shift) + 0.5))
            target = rounded if shift >= 0.0 else -rounded
            inside = (target >= 0) & (target < width)
            seen = np.float64(gt_right[y, min(max(target, 0), width - 1)])
            agree = (seen > 0.0) & (seen < np.inf) & (abs(d - seen) <= 1.0)
            occluded[y, x] = ok and not (inside and agree)
    return occluded


@njit(cache=True, nogil=True)
def visibility_labels(
    flat_occluded: np.ndarray, flat_jump: np.ndarray, flat_labels: np.ndarray
) -> None:  # pragma: no cover
    """Class per pixel: 0 occluded, else 1 near a jump (boundary), else 2 (interior)."""
    for i in range(flat_labels.shape[0]):
        flat_labels[i] = 0 if flat_occluded[i] else (1 if flat_jump[i] else 2)


@njit(cache=True, nogil=True)
def jump_mask(
    gt: np.ndarray, valid: np.ndarray, gap: float, jumps: np.ndarray
) -> None:  # pragma: no cover
    """1 in ``jumps`` (uint8 zeros) at both ends of every 4-neighbour jump > ``gap`` between valid points."""
    height, width = gt.shape
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
def add_labels(
    flat_cells: np.ndarray, flat_labels: np.ndarray, stride: int
) -> None:  # pragma: no cover
    """``cells += labels · stride`` in place on flat arrays (one pass, no temporary)."""
    for i in range(flat_cells.shape[0]):
        flat_cells[i] += flat_labels[i] * stride
