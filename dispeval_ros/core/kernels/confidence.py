"""The confidence measures' accumulation: per cell, sums by confidence level and by error bin.

A confidence level ranks pixels (0: the most confident); the last level holds the pixels
with no estimate or no confidence. Summing each level's terms (and, for the oracle, each
error bin's) makes sparsification curves exact when pooled: a sequence's curve is the curve
of its summed levels.
"""

from __future__ import annotations

import math

import numpy as np

from dispeval_ros.core.kernels._jit import njit

# Columns of a level's row (ConfidenceSums): points, Σ|e|, Σ|ΔZ|, the D1 count, then one count
# per threshold.
LEVEL_N = 0
LEVEL_SUM_E = 1
LEVEL_SUM_EZ = 2
LEVEL_D1 = 3
LEVEL_BAD = 4
"""The first ``e > threshold`` count; one per threshold follows."""
# Columns of a cell's counters.
COUNT_MISSING = 0
COUNT_UNRATED = 1
COUNT_CLAMPED = 2
COUNTERS = 3
CLAMPED = 1 << 16
"""The flag of a level whose confidence was outside the preset's range."""
LEVEL_MASK = CLAMPED - 1
# The oracle's error bins: 0 below 2**ERROR_LOW_EXPONENT, then ERROR_SUBBINS per octave up to
# 2**ERROR_HIGH_EXPONENT, then one bin above.
ERROR_LOW_EXPONENT = -10
ERROR_HIGH_EXPONENT = 10
ERROR_SUBBINS = 16
ERROR_BINS = (ERROR_HIGH_EXPONENT - ERROR_LOW_EXPONENT) * ERROR_SUBBINS + 2
D1_ABSOLUTE = 3.0
D1_RELATIVE = 0.05


_LOW_BITS = int(np.array(2.0**ERROR_LOW_EXPONENT).view(np.int64)) >> 48
"""Bits 48 and up of 2**ERROR_LOW_EXPONENT as a float64: its exponent, 4 mantissa bits zero."""
DROPPED_BIN = ERROR_BINS
"""The spare bin of the points not scored (dropped with it)."""


def error_bins(errors: np.ndarray) -> np.ndarray:
    """The oracle's bin of each absolute error: 1/16-octave bins, 0 below 2⁻¹⁰.

    A bin's errors differ by less than 1/16 of its lower edge; the last bin is open above.
    Written with numpy: the kernel reads the same bits (the float64's exponent and its four
    leading mantissa bits).
    """
    bits = np.ascontiguousarray(errors, dtype=np.float64).view(np.int64) >> 48
    return np.clip(bits - _LOW_BITS + 1, 0, ERROR_BINS - 1)


@njit(cache=True, nogil=True)
def gather_lut_levels(
    confidence: np.ndarray, order: np.ndarray, lut: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """Each evaluated pixel's level (partition order) of an 8-bit confidence: ``lut[value]``."""
    for k in range(order.shape[0]):
        out[k] = lut[confidence[order[k]]]


@njit(cache=True, nogil=True)
def gather_levels(
    confidence: np.ndarray,
    order: np.ndarray,
    low: float,
    high: float,
    higher_is_better: bool,
    levels: int,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Each evaluated pixel's confidence level (partition order), ``| CLAMPED`` if clamped.

    The value's place in ``[low, high]``, read from the most confident end, is cut in
    ``levels`` equal bins; values outside the range take the nearest end (flagged). NaN:
    level ``levels`` (no confidence).
    """
    scale = levels / (high - low)
    for k in range(order.shape[0]):
        value = np.float64(confidence[order[k]])
        if math.isnan(value):
            out[k] = levels
            continue
        flag = CLAMPED if (value < low) | (value > high) else 0
        value = min(max(value, low), high)
        place = (high - value) if higher_is_better else (value - low)
        out[k] = min(int(place * scale), levels - 1) | flag


@njit(cache=True, nogil=True, error_model="numpy")
def _bins(terms: np.ndarray, rows: np.ndarray, scored: int, out: np.ndarray) -> None:
    """Each term's error bin (:func:`error_bins`), :data:`DROPPED_BIN` where not scored."""
    bits = terms.view(np.int64)
    for k in range(terms.shape[0]):
        where = min(max((bits[k] >> 48) - _LOW_BITS + 1, 0), ERROR_BINS - 1)
        out[k] = where if rows[k] < scored else DROPPED_BIN


@njit(cache=True, nogil=True, error_model="numpy")
def _pixel_terms(
    values: np.ndarray,
    gt_sorted: np.ndarray,
    level_of: np.ndarray,
    levels: int,
    thresholds: np.ndarray,
    missing_weight: float,
    shift: float,
    fb: float,
    depth_offset: float,
    mu: float,
    depth: bool,
    terms: np.ndarray,
    depth_terms: np.ndarray,
    grades: np.ndarray,
    rows: np.ndarray,
    bins: np.ndarray,
    depth_bins: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Every point's error, depth error, table column, level row and error bins: flat passes.

    ``rows``: the level's row, ``levels`` for a missing estimate, ``levels + 1`` (a row that
    is dropped) for one not scored (``ignore``); ``grades``: 2 + the bad class.
    """
    t0, t1, t2, t3 = thresholds[0], thresholds[1], thresholds[2], thresholds[3]
    t4, t5, t6, t7 = thresholds[4], thresholds[5], thresholds[6], thresholds[7]
    doffs = depth_offset - mu
    dropped = levels if missing_weight != 0.0 else levels + 1
    for k in range(values.shape[0]):
        raw = np.float64(values[k])
        d = np.float64(gt_sorted[k])
        e = abs(abs(raw) + shift - d)
        terms[k] = e
        count = (e > t0) + (e > t1) + (e > t2) + (e > t3) + (e > t4) + (e > t5) + (e > t6)
        count += e > t7
        grades[k] = 2 + 2 * count + ((e > D1_ABSOLUTE) & (e > D1_RELATIVE * d))
        rows[k] = (level_of[k] & LEVEL_MASK) if raw > 0.0 else dropped
    _bins(terms, rows, levels + 1, bins)
    if not depth:
        return
    for k in range(values.shape[0]):
        inverse_d = max(np.float64(gt_sorted[k]) + doffs, mu)
        inverse_e = max(abs(np.float64(values[k])) + shift + doffs, mu)
        depth_terms[k] = fb * abs(inverse_d - inverse_e) / (inverse_d * inverse_e)
    _bins(depth_terms, rows, levels + 1, depth_bins)


@njit(cache=True, nogil=True, error_model="numpy")
def accumulate_levels(
    values: np.ndarray,
    gt_sorted: np.ndarray,
    level_of: np.ndarray,
    offsets: np.ndarray,
    levels: int,
    thresholds: np.ndarray,
    missing_weight: float,
    shift: float,
    fb: float,
    depth_offset: float,
    mu: float,
    depth: bool,
    table: np.ndarray,
    errors: np.ndarray,
    depth_errors: np.ndarray,
    counters: np.ndarray,
    scratch_float: np.ndarray,
    scratch_int: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Sum each cell's terms by confidence level, and by error bin for the oracle.

    ``values``: the estimate gathered in partition order (validity in the sign, scored
    ``|v| + shift``), ``level_of``: each pixel's level and flag (:func:`gather_levels`). A
    missing estimate goes to the last level (``levels``; ``ignore``, ``missing_weight`` 0:
    not scored). ``table[cell, level]``: Σ|e|, Σ|ΔZ|, then the points of each bad class
    ``c = 2·#{j: e > thresholds[j]} + D1`` (one store per point for every bad count;
    ``thresholds`` padded with inf to 8); ``errors[cell, bin]`` and ``depth_errors[cell, bin]``:
    points and Σ of the absolute (depth) error per bin (:func:`error_bins`). The depth error is
    the SZE kernel's: ``Z = f·B / max(d + doffs, μ)``. The terms are computed first in flat
    passes, then scattered; ``table`` and the bins have a spare last row (points not scored).
    ``scratch_float`` (2 × points) and ``scratch_int`` (4 × points) are the caller's reused
    buffers: fresh megabyte arrays cost more page faults than the passes take.
    """
    terms, depth_terms = scratch_float[0], scratch_float[1]
    grades, rows, bins, depth_bins = scratch_int[0], scratch_int[1], scratch_int[2], scratch_int[3]
    if not depth:
        depth_terms[:] = 0.0
        depth_bins[:] = DROPPED_BIN
    _pixel_terms(
        values, gt_sorted, level_of, levels, thresholds, missing_weight, shift, fb,
        depth_offset, mu, depth, terms, depth_terms, grades, rows, bins, depth_bins,
    )  # fmt: skip
    for cell in range(offsets.shape[0] - 1):
        start, stop = offsets[cell], offsets[cell + 1]
        for k in range(start, stop):
            row, e, ez = rows[k], terms[k], depth_terms[k]
            table[cell, row, 0] += e
            table[cell, row, 1] += ez
            table[cell, row, grades[k]] += 1.0
            errors[cell, bins[k], 0] += 1.0
            errors[cell, bins[k], 1] += e
            depth_errors[cell, depth_bins[k], 0] += 1.0
            depth_errors[cell, depth_bins[k], 1] += ez
        missing = unrated = clamped = 0
        for k in range(start, stop):
            missing += 1 if values[k] <= 0 else 0
            unrated += 1 if (rows[k] == levels) & (values[k] > 0) else 0
            clamped += level_of[k] >> 16
        counters[cell, COUNT_MISSING] = missing
        counters[cell, COUNT_UNRATED] = unrated
        counters[cell, COUNT_CLAMPED] = clamped
