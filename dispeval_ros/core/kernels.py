"""Compiled per-pixel loops: the only place where the engine touches every pixel.

Everything here is numba-compiled (cached on disk) and works on plain arrays. The scoring
path is two passes per method: :func:`normalise_estimate` (validity + the missing-estimate
policy, row by row) and :func:`accumulate_cells` (one fused pass over the valid-GT pixels in
partition order, summing every measure's terms per cell). GT-side terms are prepared once
per ground-truth map by the partition.
"""

from __future__ import annotations

import math

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


@njit(cache=True, nogil=True, inline="always")
def _float32_bounds(lo: float, hi: float) -> tuple[np.float32, np.float32]:  # pragma: no cover
    """``[lo, hi]`` as float32 bounds that select the same float32 values, never infinity.

    Comparing float32 values with float32 bounds, not float64 ones, halves a pass's vector
    width cost (no widening). NaN bounds stay NaN (nothing is valid).
    """
    lo32 = np.float32(lo)
    if lo32 < lo:
        lo32 = np.nextafter(lo32, np.float32(np.inf))
    hi32 = np.float32(hi)
    if hi32 > hi:
        hi32 = np.nextafter(hi32, np.float32(-np.inf))
    largest = np.float32(np.finfo(np.float32).max)
    if hi32 > largest:  # noqa: PLR1730 - not min(): a NaN bound must stay NaN
        hi32 = largest
    return lo32, hi32


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy")
def _code_row(
    row: np.ndarray,
    lo: np.float32,
    hi: np.float32,
    base: np.float32,
    hole: np.float32,
    out: np.ndarray,
) -> int:  # pragma: no cover
    """Copy one row with validity in the sign; the number of valid values.

    Valid (``lo ≤ value ≤ hi``) → ``value − base`` (> 0, as ``base < lo``); missing →
    ``hole`` (≤ 0). ``lo`` and ``hi`` come from :func:`_float32_bounds` (so ``hi`` also
    excludes infinity).
    """
    count = 0
    for x in range(row.shape[0]):
        value = row[x]
        valid = (value >= lo) & (value <= hi)
        out[x] = value - base if valid else hole
        count += np.int32(valid)
    return count


@njit(cache=True, nogil=True, inline="always")
def _all_valid8(row: np.ndarray, x: np.uint64) -> bool:  # pragma: no cover - compiled
    """Whether ``row[x:x+8]`` are all valid (one branch for eight values)."""
    valid = row[x] > 0.0
    for offset in range(1, 8):
        valid &= row[x + np.uint64(offset)] > 0.0
    return valid


@njit(cache=True, nogil=True)
def _fill_row_gaps(out: np.ndarray) -> None:  # pragma: no cover - compiled
    """KITTI background interpolation of one coded row that has at least one valid value.

    Unsigned indices: numba then tests no negative index on every access (a fifth faster).
    """
    width = np.uint64(out.shape[0])
    one = np.uint64(1)
    eight = np.uint64(8)
    x = np.uint64(0)
    while True:
        while x + eight <= width and _all_valid8(out, x):  # skip a run of valid values
            x += eight
        while x < width and out[x] > 0.0:
            x += one
        if x == width:
            return
        gap_start = x
        while x < width and not out[x] > 0.0:
            x += one
        if gap_start == 0:
            fill = out[x]  # leading gap: the first valid value
        elif x == width:
            fill = out[gap_start - one]  # trailing gap: the last valid value
        else:
            fill = min(out[gap_start - one], out[x])  # the farther neighbour
        k = gap_start
        while k < x:  # a loop, not a slice assignment: much less to compile
            out[k] = -fill
            k += one


#: The lower bound that makes "valid" mean "> 0" (files, GT, unset ranges): the smallest
#: positive double, which :func:`_float32_bounds` raises to the smallest positive float32.
POSITIVE = 5e-324


def coding(lo: float, offset: float = 0.0) -> tuple[float, float]:
    """``(base, shift)`` of an estimate valid from ``lo`` up, scored as ``value − offset``.

    The coded value of a valid estimate is ``value − base`` (float32), so it is > 0 even for
    a valid 0 or negative value (a DisparityImage's ``[min_disparity, max_disparity]``); the
    kernels score ``|coded| + shift`` with ``shift = base − offset``, and a missing estimate
    coded as ``shift`` scores as 0. ``base`` is 0 (the coded value is the value itself, bit
    for bit) whenever every valid value is > 0 and ``offset`` ≥ 0; else the smallest normal
    float32 below 0 (valid zeros: exact) or a power of two below ``2·lo`` and ``2·offset``
    (exact for values on a 1/16 px grid, float32-rounded otherwise).
    """
    floor = max(min(lo if math.isfinite(lo) else 0.0, offset), -(2.0**126))  # float32 range
    tiny = float(np.finfo(np.float32).tiny)
    if floor > 0 or (floor == 0 and lo > 0):
        base = 0.0
    elif floor > -tiny:
        base = -tiny
    else:
        base = -(2.0 ** math.ceil(math.log2(-2.0 * floor)))
    return base, base - offset


@njit(cache=True, nogil=True)
def normalise_estimate(
    est: np.ndarray,
    lo: float,
    hi: float,
    base: float,
    shift: float,
    policy: int,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Write the estimate to ``out`` with validity in the sign bit.

    ``out > 0``: a valid estimate (finite and within ``[lo, hi]``), coded ``value − base``.
    ``out <= 0``: missing; ``-out`` is the coded value to score (KITTI background
    interpolation under ``interpolate``, else ``shift``: a value 0). The value scored is
    ``|out| + shift`` (see :func:`coding`; ``base = shift = 0``: the value itself).
    """
    height, width = est.shape
    first_row = -1
    last_row = -1
    lo32, hi32 = _float32_bounds(lo, hi)
    base32 = np.float32(base)
    hole = np.float32(shift)
    for y in range(height):
        count = _code_row(est[y], lo32, hi32, base32, hole, out[y])
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
    estimate: np.ndarray,
    order: np.ndarray,
    lo: float,
    hi: float,
    base: float,
    shift: float,
    coded: bool,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Gather the estimate at the evaluated pixels (partition order), validity in the sign.

    ``out[k] > 0``: a valid estimate. ``out[k] <= 0``: missing, to be scored as
    ``-out[k] + shift`` (the interpolated value when ``estimate`` was coded by
    :func:`normalise_estimate`, otherwise 0). Coded as :func:`normalise_estimate` codes.
    """
    for k in range(order.shape[0]):  # a plain gather, then a contiguous pass: both vectorise
        out[k] = estimate[order[k]]
    if coded:  # validity is already in the sign
        return
    lo32, hi32 = _float32_bounds(lo, hi)
    base32 = np.float32(base)
    hole = np.float32(shift)
    for k in range(order.shape[0]):
        raw = out[k]
        valid = (raw >= lo32) & (raw <= hi32)
        out[k] = raw - base32 if valid else hole


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy")
def _disparity_sums(
    values: np.ndarray,
    gt: np.ndarray,
    fb: float,
    depth_offset: float,
    mu: float,
    thresholds: np.ndarray,
    extra: bool,
    missing_weight: float,
    shift: float,
) -> tuple[float, ...]:  # pragma: no cover
    """One cell's disparity-domain sums: valid, evaluated, e, e², rel, SZE, BMPRE, D1, bad counts.

    The bad counts are those of the :data:`MAX_THRESHOLDS` ``thresholds`` (δ first; ``inf``:
    counts 0), the others only ``if extra`` (a loop-invariant test: the compiler makes two
    loops). The value scored is ``|raw| + shift`` (:func:`coding`); an estimate with
    ``E + doffs < 0`` (a valid negative disparity) has the far depth ``f·B/μ`` in SZE, as a
    value ``E + doffs = 0`` has. Contiguous slices and no branches, so it vectorises. The bad
    counts cost little here (a comparison each) and much as passes of their own (each reads both
    arrays again).
    """
    n_valid = 0.0
    n_eval = 0.0
    sum_e = 0.0
    sum_e2 = 0.0
    sum_rel = 0.0
    sze = 0.0
    bmpre = 0.0
    d1 = 0.0
    bad0 = bad1 = bad2 = bad3 = bad4 = bad5 = bad6 = bad7 = 0.0
    delta = thresholds[0]
    t1, t2, t3, t4 = thresholds[1], thresholds[2], thresholds[3], thresholds[4]
    t5, t6, t7 = thresholds[5], thresholds[6], thresholds[7]
    for k in range(values.shape[0]):
        raw = np.float64(values[k])
        weight = 1.0 if raw > 0.0 else missing_weight
        value = abs(raw) + shift
        d = np.float64(gt[k])
        e = abs(value - d)
        rel = e / d
        n_valid += 1.0 if raw > 0.0 else 0.0
        n_eval += weight
        sum_e += weight * e
        sum_e2 += weight * e * e
        sum_rel += weight * rel
        # E + doffs < 0: Z_E = f·B/μ, so |Z_D − Z_E| = f·B·|D + doffs| / ((D + o)·μ).
        far = value + depth_offset < mu
        e_z = abs(d + depth_offset - mu) if far else e
        sze += weight * fb * e_z / abs((d + depth_offset) * (mu if far else value + depth_offset))
        bmpre += weight * rel if e > delta else 0.0
        d1 += weight if (e > 3.0 and e > 0.05 * d) else 0.0
        bad0 += weight if e > delta else 0.0
        if extra:
            bad1 += weight if e > t1 else 0.0
            bad2 += weight if e > t2 else 0.0
            bad3 += weight if e > t3 else 0.0
            bad4 += weight if e > t4 else 0.0
            bad5 += weight if e > t5 else 0.0
            bad6 += weight if e > t6 else 0.0
            bad7 += weight if e > t7 else 0.0
    return (
        n_valid, n_eval, sum_e, sum_e2, sum_rel, sze, bmpre, d1,
        bad0, bad1, bad2, bad3, bad4, bad5, bad6, bad7,
    )  # fmt: skip


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy")
def _depth_sums(
    values: np.ndarray,
    gt: np.ndarray,
    fb: float,
    depth_offset: float,
    mu: float,
    missing_weight: float,
    shift: float,
) -> tuple[float, float, float, float]:  # pragma: no cover
    """One cell's depth-domain sums: Σ|Z_E − Z_D|, Σ(Z_E − Z_D)², Σ|Z_E − Z_D|/Z_D, Σ(1/Z_E − 1/Z_D)².

    ``Z = f·B / max(d + doffs, μ)``: exact for every point with ``d + doffs ≥ μ``, and a
    missing estimate scored as 0 costs a large but finite depth.
    """
    doffs = depth_offset - mu
    sum_ez = sum_ez2 = sum_relz = sum_iz2 = 0.0
    for k in range(values.shape[0]):
        raw = np.float64(values[k])
        weight = 1.0 if raw > 0.0 else missing_weight
        inverse_d = max(np.float64(gt[k]) + doffs, mu)  # f·B / Z of the GT
        inverse_e = max(abs(raw) + shift + doffs, mu)
        ez = fb * abs(inverse_d - inverse_e) / (inverse_d * inverse_e)
        sum_ez += weight * ez
        sum_ez2 += weight * ez * ez
        sum_relz += weight * abs(inverse_d - inverse_e) / inverse_e  # |Z_E − Z_D| / Z_D
        iz = (inverse_e - inverse_d) / fb
        sum_iz2 += weight * iz * iz
    return sum_ez, sum_ez2, sum_relz, sum_iz2


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
    shift: float,
    sums: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Accumulate every measure's terms per cell in one pass over the valid-GT points.

    ``values`` comes from :func:`gather_estimate` and ``gt_sorted`` holds ``D`` in the
    same (partition) order; ``offsets`` delimit the cells. ``depth_offset`` is
    ``doffs + μ``; the SZE term ``|f·B/(D+o) − f·B/(E+o)|`` is computed as the equal
    ``f·B·e / |(D+o)(E+o)|``, which has no cancellation; the depth-domain terms use ``μ`` only
    as a floor of ``d + doffs`` (see :func:`_depth_sums`). ``thresholds[0]`` is δ (bmp,
    bmpre), the others the bad-x thresholds, then ``inf`` (unused).
    ``missing_weight`` is 0 under the ``ignore`` policy (missing points leave the error
    measures) and 1 otherwise. The depth-domain columns are summed only when
    ``depth_terms`` (otherwise they stay 0; measures are derived from requested fields only).
    The value of a coded estimate is ``|values[k]| + shift`` (:func:`coding`).
    """
    extra = thresholds[1] < np.inf  # bad_X thresholds are listed first, then inf
    for cell in range(offsets.shape[0] - 1):
        start = offsets[cell]
        stop = offsets[cell + 1]
        cell_values = values[start:stop]
        cell_gt = gt_sorted[start:stop]
        terms = _disparity_sums(
            cell_values, cell_gt, fb, depth_offset, mu, thresholds, extra, missing_weight, shift
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
        for t in range(MAX_THRESHOLDS):
            row[FIELD_BAD + t] += terms[8 + t]
        if depth_terms:  # as costly as all the others (two more divisions per point)
            depth = _depth_sums(cell_values, cell_gt, fb, depth_offset, mu, missing_weight, shift)
            row[FIELD_SUM_EZ] += depth[0]
            row[FIELD_SUM_EZ2] += depth[1]
            row[FIELD_SUM_RELZ] += depth[2]
            row[FIELD_SUM_IZ2] += depth[3]


#: Spare z-buffer slots that pixels landing nowhere write to in turn (never read): one slot for
#: all of them would chain every such store to the one before.
SPARE_SLOTS = 16


@njit(cache=True, nogil=True, error_model="numpy")
def forward_warp_occlusion(
    gt: np.ndarray,
    valid: np.ndarray,
    tolerance: float,
    occluded: np.ndarray,
    zbuffer: np.ndarray,
    target: np.ndarray,
    slot: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Occlusion of the left view from the left GT alone (z-buffer forward warping).

    Each valid point ``(x, y)`` lands at ``floor(x − d + 0.5)`` in the right view. It is
    occluded when it lands outside the image, or another point lands on the same position
    with a disparity larger by more than ``tolerance`` (≥ 0; that point is nearer and hides
    it). Writes every pixel of ``occluded``. Per row, a vectorised pass finds where each pixel
    lands; a point can only be hidden by a point to its right, so one right-to-left pass
    (:func:`_row_hidden`) reads and writes the z-buffer. The caller allocates ``zbuffer``
    (float32, width + :data:`SPARE_SLOTS` + 1), ``target`` and ``slot`` (uint32, width).
    """
    height, width = gt.shape
    never = width + SPARE_SLOTS  # a slot that stays −inf: what points nothing can hide read
    zbuffer[never] = -np.inf
    for y in range(height):
        row = gt[y]
        ok = valid[y]
        out = occluded[y]
        for x in range(width + SPARE_SLOTS):
            zbuffer[x] = -np.inf
        for x in range(width):  # geometry: vectorises
            d = np.float64(row[x]) if ok[x] else 0.0
            landing = np.floor(min(max(x - d + 0.5, -1.0), np.float64(width)))
            lands = ok[x] & (landing >= 0.0) & (landing < width)
            out[x] = ok[x] != lands  # valid and landing outside the image
            target[x] = np.uint32(landing) if lands else np.uint32(never)
            slot[x] = np.uint32(landing) if lands else np.uint32(width + (x & (SPARE_SLOTS - 1)))
        _row_hidden(row, target, slot, tolerance, zbuffer, out)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _row_hidden(
    row: np.ndarray,
    target: np.ndarray,
    slot: np.ndarray,
    tolerance: float,
    zbuffer: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """One row's z-buffer, right to left: marks in ``out`` the points a point to their right hides.

    Branch-free (holes and occlusions are not predictable) and with unsigned indices (no
    negative-index wrap-around). Inlined: as fast, and one function less to compile.
    """
    width = row.shape[0]
    for i in range(width):
        x = np.uint64(width - 1 - i)
        hidden = np.float64(zbuffer[target[x]]) > np.float64(row[x]) + tolerance
        here = slot[x]
        zbuffer[here] = max(zbuffer[here], row[x])
        out[x] = out[x] | hidden


@njit(cache=True, nogil=True)
def threshold_labels(
    flat_values: np.ndarray, low: float, high: float, flat_labels: np.ndarray
) -> None:  # pragma: no cover
    """Class 0 above ``high``, 1 in ``(low, high]``, 2 otherwise (near / mid / far)."""
    for i in range(flat_values.shape[0]):
        v = flat_values[i]
        flat_labels[i] = 0 if v > high else (1 if v > low else 2)


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


#: Pixels per run of one cell, on average, from which :func:`partition_cells` works run by run.
RUN_PIXELS = 8


@njit(cache=True, nogil=True, inline="always")
def _run_end(flat_cells: np.ndarray, start: np.uint64, end: np.uint64) -> np.uint64:
    """Where the run of equal cells that begins at ``start`` ends (16 at a time, vectorised)."""
    cell = flat_cells[start]
    stop = start + np.uint64(1)
    chunk = np.uint64(16)
    while stop + chunk <= end:
        differ = np.int32(0)
        for offset in range(16):
            differ |= flat_cells[stop + np.uint64(offset)] ^ cell
        if differ != 0:
            break
        stop += chunk
    while stop < end and flat_cells[stop] == cell:
        stop += np.uint64(1)
    return stop


@njit(cache=True, nogil=True)
def partition_cells(
    flat_valid: np.ndarray,
    flat_occluded: np.ndarray,
    flat_near_jump: np.ndarray,
    visibility_stride: int,
    flat_values: np.ndarray,
    low: float,
    high: float,
    depth_stride: int,
    flat_labels: np.ndarray,
    labels_stride: int,
    flat_cells: np.ndarray,
    next_slot: np.ndarray,
    offsets: np.ndarray,
    order: np.ndarray,
    sorted_values: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """The cell of every pixel, the evaluated pixels sorted by cell and their values gathered.

    A valid pixel's cell is ``visibility · visibility_stride + depth · depth_stride + label ·
    labels_stride`` with the visibility class (0 occluded, else 1 near a jump, else 2) and the
    depth class (0 above ``high``, 1 in ``(low, high]``, 2 otherwise) computed here, and
    ``label`` from a label image (several criterion sets folded into one); ``-1`` elsewhere.
    An input whose stride is 0 is not used (any array of the right type will do; for the labels
    even ``flat_cells``).
    Then a stable counting sort: ``order[offsets[c]:offsets[c + 1]]`` are cell ``c``'s
    pixels, and ``sorted_values`` (unless empty) ``flat_values`` in that order. Dense GT gives
    long runs of one cell along image rows: whole runs (at least :data:`RUN_PIXELS` pixels on
    average) are counted and placed with vectorised copies; otherwise (sparse GT) pixels are
    counted one at a time on four interleaved counters. The caller allocates (kernels that
    allocate and return arrays take twice as long to compile): ``next_slot`` zeros
    ``(4, cells + 1)``, ``offsets`` ``(cells + 1)``, ``order`` and ``sorted_values`` one entry
    per valid pixel.
    """
    n_cells = offsets.shape[0] - 1
    pixels = flat_cells.shape[0]
    for i in range(pixels):  # branch-free: vectorised
        visibility = 0 if flat_occluded[i] else (1 if flat_near_jump[i] else 2)
        v = flat_values[i]
        depth = 0 if v > high else (1 if v > low else 2)
        c = visibility * visibility_stride + depth * depth_stride
        flat_cells[i] = c if flat_valid[i] else -1
    if labels_stride != 0:  # a loop of its own: ``flat_labels`` may be ``flat_cells`` otherwise
        for i in range(pixels):  # a negative label leaves the pixel out
            c = flat_cells[i] + flat_labels[i] * labels_stride
            flat_cells[i] = max(c, -1) if flat_valid[i] else -1
    # Indices are unsigned below (cells are >= -1): no negative-index wrap-around is computed,
    # which lets the loops vectorise.
    end = np.uint64(pixels)
    changes = 0
    for i in range(1, pixels):  # vectorised
        changes += flat_cells[np.uint64(i)] != flat_cells[np.uint64(i - 1)]
    long_runs = changes * RUN_PIXELS < pixels  # dense GT: count and place whole runs
    if long_runs:
        start = np.uint64(0)
        while start < end:
            stop = _run_end(flat_cells, start, end)
            next_slot[0, np.uint64(flat_cells[start] + 1)] += np.int64(stop - start)
            start = stop
    else:  # short runs (sparse GT): one pixel at a time, interleaved counters
        for i in range(pixels):
            next_slot[np.uint64(i & 3), np.uint64(flat_cells[i] + 1)] += 1
    offsets[0] = 0
    for c in range(n_cells):
        offsets[c + 1] = offsets[c] + next_slot[0, c + 1] + next_slot[1, c + 1]
        offsets[c + 1] += next_slot[2, c + 1] + next_slot[3, c + 1]
    for c in range(n_cells):
        next_slot[0, c] = offsets[c]  # from here on: where each cell's next pixel goes
    slots = next_slot[0]
    gather = sorted_values.shape[0] > 0
    if long_runs:
        start = np.uint64(0)
        while start < end:
            cell = flat_cells[start]
            stop = _run_end(flat_cells, start, end)
            if cell >= 0:
                slot = np.uint64(slots[cell])
                length = stop - start
                for k in range(length):
                    order[slot + np.uint64(k)] = np.int32(start + np.uint64(k))
                if gather:
                    for k in range(length):
                        sorted_values[slot + np.uint64(k)] = flat_values[start + np.uint64(k)]
                slots[cell] = np.int64(slot + length)
            start = stop
        return
    current = np.uint64(0)
    position = np.uint64(slots[0])
    for i in range(pixels):  # a run of one cell is placed from a register
        cell = flat_cells[i]
        if cell >= 0:
            c = np.uint64(cell)
            if c != current:
                slots[current] = position
                current = c
                position = np.uint64(slots[c])
            order[position] = i
            if gather:
                sorted_values[position] = flat_values[i]
            position += np.uint64(1)


@njit(cache=True, nogil=True)
def valid_points(flat_values: np.ndarray, flat_valid: np.ndarray) -> None:  # pragma: no cover
    """``flat_valid``: each value is finite and > 0 (NaN fails both tests); vectorised."""
    for k in range(flat_values.shape[0]):
        i = np.uint64(k)  # unsigned: no wrap-around test in the loop
        flat_valid[i] = (flat_values[i] > 0) & (flat_values[i] < np.inf)


@njit(cache=True, nogil=True)
def pack_valid(
    flat_values: np.ndarray, flat_valid: np.ndarray, packed: np.ndarray
) -> int:  # pragma: no cover - compiled
    """Copy the valid values to the front of ``packed`` (branch-free); their number."""
    count = 0
    for i in range(flat_values.shape[0]):
        packed[count] = flat_values[i]  # overwritten by the next value unless this one is valid
        count += 1 if flat_valid[i] else 0
    return count


@njit(cache=True, nogil=True)
def valid_range(
    bits: np.ndarray, valid: np.ndarray, limits: np.ndarray
) -> None:  # pragma: no cover
    """The bit patterns of the smallest and largest valid value, in ``limits`` (vectorised).

    ``bits``: the values viewed as signed integers of their size. Valid values are finite and
    > 0, whose bit patterns sort as the values do, and integer minima vectorise where float
    ones (NaN rules) do not. The caller fills ``limits`` with the type's largest value and −1.
    """
    top = limits[0]
    bottom = limits[1]
    lowest = top
    highest = bottom
    for k in range(bits.shape[0]):
        i = np.uint64(k)
        lowest = min(lowest, bits[i] if valid[i] else top)
        highest = max(highest, bits[i] if valid[i] else bottom)
    limits[0] = lowest
    limits[1] = highest


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


@njit(cache=True, nogil=True)
def jump_marks(
    gt: np.ndarray, valid: np.ndarray, gap: float, jumps: np.ndarray, rows: np.ndarray
) -> int:  # pragma: no cover - compiled
    """Mark both ends of every 4-neighbour jump > ``gap`` between valid points; count connected points.

    Writes every pixel of ``jumps`` (bool). Returns how many valid points have a valid
    neighbour both vertically and horizontally (the sparse-GT statistic of
    ``criteria.is_sparse``), from the same pass. Branch-free rows; ``rows`` is bool scratch
    ``(5, width + 1)``: entry ``x + 1`` of the pair rows is about columns ``x`` and ``x + 1``.
    """
    height, width = gt.shape
    across = rows[0]  # a jump between columns x and x + 1 (at x + 1)
    pairs = rows[1]  # both columns x and x + 1 valid (at x + 1)
    down = rows[2]  # a jump between this row and the next
    above = rows[3]  # ``down`` of the previous row
    nothing = rows[4]
    for x in range(width + 1):
        across[x] = pairs[x] = above[x] = nothing[x] = False
    connected = 0
    for y in range(height):
        row = gt[y]
        ok = valid[y]
        for x in range(width - 1):
            pair = ok[x] & ok[x + 1]
            pairs[x + 1] = pair
            across[x + 1] = pair & (abs(row[x] - row[x + 1]) > gap)
        up = valid[y - 1] if y > 0 else nothing
        ok_below = valid[y + 1] if y + 1 < height else nothing
        below = gt[y + 1] if y + 1 < height else row
        for x in range(width):
            down[x] = ok[x] & ok_below[x] & (abs(row[x] - below[x]) > gap)
        out = jumps[y]
        for x in range(width):
            out[x] = across[x] | across[x + 1] | down[x] | above[x]
            connected += (pairs[x] | pairs[x + 1]) & (up[x] | ok_below[x])
        above, down = down, above
    return connected
