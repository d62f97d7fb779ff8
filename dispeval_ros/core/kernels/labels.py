"""Per-pixel labels of the criteria: occlusion (z-buffer, left-right), visibility, classes, jumps."""

from __future__ import annotations

import numpy as np

from dispeval_ros.core.kernels._jit import njit

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
