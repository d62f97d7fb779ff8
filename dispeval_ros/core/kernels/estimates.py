"""Estimate coding: validity, the missing-estimate policy and the gather into partition order."""

from __future__ import annotations

import math

import numpy as np

from dispeval_ros.core.kernels._jit import _FAST, njit

POLICY_INTERPOLATE = 0
POLICY_THESIS = 1
POLICY_IGNORE = 2


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
