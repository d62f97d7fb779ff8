"""The fused accumulation of every measure's terms per cell (disparity and depth sums)."""

from __future__ import annotations

import numpy as np

from dispeval_ros.core.kernels._jit import _FAST, njit
from dispeval_ros.core.kernels.layout import (
    FIELD_BAD,
    FIELD_BMPRE,
    FIELD_D1,
    FIELD_EVAL,
    FIELD_N,
    FIELD_SUM_E,
    FIELD_SUM_E2,
    FIELD_SUM_EZ,
    FIELD_SUM_EZ2,
    FIELD_SUM_IZ2,
    FIELD_SUM_REL,
    FIELD_SUM_RELZ,
    FIELD_SZE,
    FIELD_VALID,
    MAX_THRESHOLDS,
)


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
