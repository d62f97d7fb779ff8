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

# Columns of a level's row: points, Σ|e|, Σ|ΔZ|, the D1 count, then one count per threshold.
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


@njit(cache=True, nogil=True)
def error_bin(error: float) -> int:  # pragma: no cover - compiled
    """The oracle's bin of an absolute error: 1/16-octave bins, so a bin's errors differ < 4.4 %."""
    if not error >= 2.0**ERROR_LOW_EXPONENT:
        return 0
    mantissa, exponent = math.frexp(error)  # error = mantissa · 2**exponent, mantissa in [½, 1)
    index = (exponent - 1 - ERROR_LOW_EXPONENT) * ERROR_SUBBINS
    index += int((mantissa - 0.5) * (2 * ERROR_SUBBINS)) + 1
    return min(index, ERROR_BINS - 1)


@njit(cache=True, nogil=True)
def gather_levels(
    confidence: np.ndarray,
    order: np.ndarray,
    lut: np.ndarray,
    low: float,
    high: float,
    higher_is_better: bool,
    levels: int,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Each evaluated pixel's confidence level (partition order), ``| CLAMPED`` if clamped.

    With a look-up table (8-bit confidences), the level is ``lut[value]``. Otherwise the
    value's place in ``[low, high]``, read from the most confident end, is cut in ``levels``
    equal bins; values outside the range take the nearest end (flagged). NaN: level
    ``levels`` (no confidence).
    """
    if lut.shape[0] > 0:
        for k in range(order.shape[0]):
            out[k] = lut[confidence[order[k]]]
        return
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
    sums: np.ndarray,
    errors: np.ndarray,
    depth_errors: np.ndarray,
    counters: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Sum each cell's terms by confidence level, and by error bin for the oracle.

    ``values``: the estimate gathered in partition order (validity in the sign, scored
    ``|v| + shift``), ``level_of``: each pixel's level and flag (:func:`gather_levels`). A missing
    estimate goes to the last level (``levels``) with weight ``missing_weight`` (``ignore``:
    0, not counted). ``sums[cell, level]``: the ``LEVEL_*`` columns; ``errors[cell, bin]`` and
    ``depth_errors[cell, bin]``: points and Σ of the absolute (depth) error per bin.
    The depth error is the SZE kernel's: ``Z = f·B / max(d + doffs, μ)``.
    """
    doffs = depth_offset - mu
    count = thresholds.shape[0]
    for cell in range(offsets.shape[0] - 1):
        for k in range(offsets[cell], offsets[cell + 1]):
            raw = np.float64(values[k])
            level = level_of[k] & LEVEL_MASK
            counters[cell, COUNT_CLAMPED] += 1.0 if level_of[k] & CLAMPED else 0.0
            if raw <= 0.0:
                counters[cell, COUNT_MISSING] += 1.0
                if missing_weight == 0.0:
                    continue
                level = levels
            elif level == levels:
                counters[cell, COUNT_UNRATED] += 1.0
            d = np.float64(gt_sorted[k])
            e = abs(abs(raw) + shift - d)
            row = sums[cell, level]
            row[LEVEL_N] += 1.0
            row[LEVEL_SUM_E] += e
            row[LEVEL_D1] += 1.0 if (e > D1_ABSOLUTE) & (e > D1_RELATIVE * d) else 0.0
            for j in range(count):
                row[LEVEL_BAD + j] += 1.0 if e > thresholds[j] else 0.0
            where = error_bin(e)
            errors[cell, where, 0] += 1.0
            errors[cell, where, 1] += e
            if depth:
                inverse_d = max(d + doffs, mu)
                inverse_e = max(abs(raw) + shift + doffs, mu)
                ez = fb * abs(inverse_d - inverse_e) / (inverse_d * inverse_e)
                row[LEVEL_SUM_EZ] += ez
                where = error_bin(ez)
                depth_errors[cell, where, 0] += 1.0
                depth_errors[cell, where, 1] += ez
