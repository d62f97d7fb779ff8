"""The fused accumulation of the pair measures' terms per cell (TEPE, relative TEPE, bad counts)."""

from __future__ import annotations

import numpy as np

from dispeval_ros.core.kernels._jit import _FAST, njit
from dispeval_ros.core.registry import MAX_THRESHOLDS, PAIR_SUM_FIELDS, pair_field_index

# Columns of the pair accumulator, as plain integers numba compiles in (from the registry).
PAIR_N = pair_field_index("n_pair")
PAIR_EVAL = pair_field_index("n_pair_eval")
PAIR_NONZERO = pair_field_index("n_pair_nonzero")
PAIR_SUM_TE = pair_field_index("sum_te")
PAIR_SUM_TE_REL = pair_field_index("sum_te_rel")
PAIR_BAD = pair_field_index("te_bad_count_0")
"""δ's bad count; the bad-x thresholds' counts follow (``MAX_THRESHOLDS`` in all)."""
PAIR_COUNT = len(PAIR_SUM_FIELDS)


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy")
def _pair_sums(
    values: np.ndarray,
    values_next: np.ndarray,
    gt: np.ndarray,
    gt_next: np.ndarray,
    thresholds: np.ndarray,
    extra: bool,
    missing_weight: float,
    shift: float,
    shift_next: float,
    epsilon: float,
) -> tuple[float, ...]:  # pragma: no cover
    """One cell's pair sums: both-GT pixels, scored, non-zero, Σe, Σe/(|ΔD|+ε), bad counts.

    ``gt_next`` holds ``D_t+1`` gathered at the cell's pixels (≤ 0: no GT there). The weight of
    a pixel is 0 without GT at t+1, else 1, times ``missing_weight`` for each frame whose
    estimate is missing (``ignore``: 0). Contiguous slices and no branches, so it vectorises.
    """
    n_pair = n_eval = n_nonzero = sum_te = sum_rel = 0.0
    bad0 = bad1 = bad2 = bad3 = bad4 = bad5 = bad6 = bad7 = 0.0
    delta = thresholds[0]
    t1, t2, t3, t4 = thresholds[1], thresholds[2], thresholds[3], thresholds[4]
    t5, t6, t7 = thresholds[5], thresholds[6], thresholds[7]
    for k in range(values.shape[0]):
        raw = np.float64(values[k])
        raw_next = np.float64(values_next[k])
        d_next = np.float64(gt_next[k])
        both = 1.0 if d_next > 0.0 else 0.0
        weight = both * (1.0 if raw > 0.0 else missing_weight)
        weight *= 1.0 if raw_next > 0.0 else missing_weight
        change = np.float64(gt[k]) - d_next
        e = abs((abs(raw) + shift) - (abs(raw_next) + shift_next) - change)
        e = e if both > 0.0 else 0.0  # no GT at t+1: d_next is a stand-in, keep the sums finite
        n_pair += both
        n_eval += weight
        n_nonzero += weight if e != 0.0 else 0.0
        sum_te += weight * e
        sum_rel += weight * e / (abs(change) + epsilon)
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
        n_pair, n_eval, n_nonzero, sum_te, sum_rel,
        bad0, bad1, bad2, bad3, bad4, bad5, bad6, bad7,
    )  # fmt: skip


@njit(cache=True, nogil=True)
def gather_next_ground_truth(
    gt_next: np.ndarray, next_cells: np.ndarray, order: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """``D_t+1`` at frame t's evaluated pixels (partition order); 0 where it has no valid GT.

    Valid: finite and > 0 (NaN fails both tests), and, when ``next_cells`` is not empty (the
    next frame's partition), evaluated there too (an official ``all`` mask of frame t+1). A
    plain gather, then contiguous passes: both vectorise.
    """
    for k in range(order.shape[0]):
        out[k] = gt_next[order[k]]
    zero = np.float32(0.0)
    for k in range(order.shape[0]):
        value = out[k]
        out[k] = value if (value > 0) & (value < np.inf) else zero
    if next_cells.shape[0] == 0:
        return
    for k in range(order.shape[0]):
        out[k] = out[k] if next_cells[order[k]] >= 0 else zero


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy")
def accumulate_pairs(
    values: np.ndarray,
    values_next: np.ndarray,
    gt_sorted: np.ndarray,
    gt_next_sorted: np.ndarray,
    offsets: np.ndarray,
    thresholds: np.ndarray,
    missing_weight: float,
    shift: float,
    shift_next: float,
    epsilon: float,
    sums: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Accumulate the pair measures' terms per cell in one pass over frame t's valid-GT pixels.

    ``values``/``values_next``: both frames' estimates gathered in frame t's partition order
    (validity in the sign, the value scored ``|v| + shift``); ``gt_sorted``: ``D_t`` in that
    order, ``gt_next_sorted``: ``D_t+1`` (:func:`gather_next_ground_truth`). The temporal
    error of a pixel is ``e = |(E_t − E_t+1) − (D_t − D_t+1)|`` at the same pixel, in float64.
    ``thresholds``: δ, then the bad-x thresholds, then ``inf``.
    """
    extra = thresholds[1] < np.inf
    for cell in range(offsets.shape[0] - 1):
        start = offsets[cell]
        stop = offsets[cell + 1]
        terms = _pair_sums(
            values[start:stop],
            values_next[start:stop],
            gt_sorted[start:stop],
            gt_next_sorted[start:stop],
            thresholds,
            extra,
            missing_weight,
            shift,
            shift_next,
            epsilon,
        )
        row = sums[cell]
        row[PAIR_N] += terms[0]
        row[PAIR_EVAL] += terms[1]
        row[PAIR_NONZERO] += terms[2]
        row[PAIR_SUM_TE] += terms[3]
        row[PAIR_SUM_TE_REL] += terms[4]
        for t in range(MAX_THRESHOLDS):
            row[PAIR_BAD + t] += terms[5 + t]
