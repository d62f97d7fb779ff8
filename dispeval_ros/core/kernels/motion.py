"""Compiled loops of the temporal measures: ego-motion reprojection (z-buffer, masks, sums).

Kept apart from :mod:`dispeval_ros.core.egomotion` (records, checks, the offset fit) because
these are the only loops that touch every pixel. Geometry, in the left rectified camera at
``t``: a pixel ``(x, y)`` with disparity ``e`` and offset ``b`` has depth ``Z = f·B/(e − b +
doffs)`` and the point ``P = Z·((x − cx)/f, (y − cy)/f, 1)``; ``Q = R·P + T`` is that point in
the camera at ``t + k``, where it lands at ``(cx + f·Qx/Qz, cy + f·Qy/Qz)`` with the
disparity ``f·B/Qz − doffs``. ``rt`` is the 3×4 ``[R | T]``; ``geo`` is ``(f, cx, cy, f·B,
doffs)``. The offset fit's loops (a sparse grid) are in :mod:`.motion_fit`.

No fast-math outside the sums (NaN and the masks' comparisons are relied on). The landing is
computed homogeneously (one division per pixel instead of two, :func:`_landing`): the same
values to about 1e-16 relative, so a status changes only where a float64 rounding decides a
tie (the tests compare every status with numpy). Per row: one vectorised pass for the
geometry, bare scalar loads for the gathers (numba's wrap-around of negative indices avoided
by unsigned ones) blended in vectorised passes, one scattered write per point into the
z-buffer, one vectorised pass for the masks and residuals.
"""

from __future__ import annotations

import numpy as np

from dispeval_ros.core.kernels._jit import _FAST, njit

# Status of a source pixel, in the order the masks are tried (the first that applies wins).
COUNTED, MISSING, BORDER, HIDDEN, MISSING_TARGET, EDGE, MOVING = range(7)
STATUSES = 7
# Accumulator columns: n, one count per status (COL_STATUS + status), then the residual sums
# of the counted pixels and one count per threshold (|r| > threshold).
COL_N = 0
COL_STATUS = 1
COL_SUM_ABS = COL_STATUS + STATUSES
COL_SUM = COL_SUM_ABS + 1
COL_SUM_SQ = COL_SUM + 1
COL_SUM_ABS_Z = COL_SUM_SQ + 1
COL_SUM_SQ_Z = COL_SUM_ABS_Z + 1
COL_BAD = COL_SUM_SQ_Z + 1


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _landing(
    row: np.ndarray,
    us: np.ndarray,
    y: int,
    rt: np.ndarray,
    geo: np.ndarray,
    offset: float,
    box: tuple[float, float, float, float],
    shape: tuple[int, int],
    scratch: Row,
    full: bool,
) -> None:  # pragma: no cover - compiled
    """Where each point of one row lands: its support's corner, weights, nearest pixel, depth.

    One vectorised pass, branch-free: a missing estimate (NaN), no depth (``s ≤ 0``) or a
    point behind the camera fail the comparisons and land nowhere (at 0, so every gather
    stays inside). Homogeneous, so one division per pixel: with ``s = e − b + doffs`` and
    ``A = R·((x − cx)/f, (y − cy)/f, 1)``, ``Q = (f·B·A + s·T)/s``, so ``w = f·B·Az + s·Tz``
    is ``Qz·s`` and ``x' = cx + f·(f·B·Ax + s·Tx)/w``, the predicted disparity ``f·B·s/w −
    doffs``. ``us``: ``(x − cx)/f`` of every column (:func:`_columns`). ``box`` is (x_lo, x_hi,
    y_lo, y_hi) of the landings kept. ``full`` (a constant where inlined): also the nearest
    pixel, ``s`` and ``w`` (the depth is ``w/s``), which the z-buffer does not need.
    """
    values, index, marks = scratch
    ss, ws, predicted = values[S], values[W], values[PREDICTED]
    wx, wy = values[WX], values[WY]
    corner, near, lands = index[CORNER], index[NEAR], marks[LANDS]
    f, cx, cy, fb, doffs = geo[0], geo[1], geo[2], geo[3], geo[4]
    v = (y - cy) / f
    ax, ay, az = fb * rt[0, 0], fb * rt[1, 0], fb * rt[2, 0]
    bx = fb * (rt[0, 1] * v + rt[0, 2])
    by = fb * (rt[1, 1] * v + rt[1, 2])
    bz = fb * (rt[2, 1] * v + rt[2, 2])
    tx, ty, tz = rt[0, 3], rt[1, 3], rt[2, 3]
    x_lo, x_hi, y_lo, y_hi = box
    height, width = shape
    for x in range(row.shape[0]):
        s = np.float64(row[x]) - offset + doffs
        u = us[x]
        w = az * u + bz + tz * s
        inverse = 1.0 / w
        xp = cx + f * (ax * u + bx + tx * s) * inverse
        yp = cy + f * (ay * u + by + ty * s) * inverse
        ok = (s > 0.0) & (w > 0.0) & (xp >= x_lo) & (xp <= x_hi) & (yp >= y_lo) & (yp <= y_hi)
        xp = xp if ok else 0.0
        yp = yp if ok else 0.0
        x0 = min(int(xp), width - 2)
        y0 = min(int(yp), height - 2)
        if full:
            ss[x] = s
            ws[x] = w
        predicted[x] = fb * s * inverse - doffs
        lands[x] = ok
        fx = xp - x0
        fy = yp - y0
        wx[x] = fx
        wy[x] = fy
        corner[x] = y0 * width + x0  # the nearest pixel: the corner, or a step right or down
        if full:
            near[x] = y0 * width + x0 + (fx >= 0.5) + width * (fy >= 0.5)


Row = tuple[np.ndarray, np.ndarray, np.ndarray]
S, W, PREDICTED, WX, WY, NEAREST, SAMPLED = 0, 1, 2, 3, 4, 5, 6
"""Rows of the float64 row scratch (``S``: ``e − b + doffs``; ``W``: ``Qz·s``)."""
CORNER, NEAR = 0, 1
"""Rows of the int64 row scratch: flat index of the support's corner and of the nearest pixel."""
LANDS, TARGET_EDGE = 0, 1
"""Rows of the bool row scratch."""


def row_buffers(width: int) -> Row:
    """Scratch of one row: float64 rows, int64 flat indices, bool rows."""
    return (
        np.empty((SAMPLED + 1, width), np.float64),
        np.empty((2, width), np.int64),
        np.empty((2, width), np.bool_),
    )


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _columns(width: int, geo: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """``u = (x − cx)/f`` of every column: one division per column, not per pixel."""
    us = np.empty(width, np.float64)
    for x in range(width):
        us[x] = (x - geo[1]) / geo[0]
    return us


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _blend(a: float, b: float, c: float, d: float, wx: float, wy: float) -> float:
    """Bilinear value at ``(wx, wy)`` of a support ``a b / c d`` (NaN when one of them is)."""
    top = a + wx * (b - a)
    return top + wy * (c + wx * (d - c) - top)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _sample(
    flat: np.ndarray, scratch: Row, width: int, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """The bilinear value of ``flat`` (an image as one row) at each landing of the row.

    One scalar loop: the four support values loaded, converted and blended (:func:`_blend`)
    at once; measured a little faster than loading them into a 4 × width scratch first and
    blending in a vectorised second pass. Unsigned indices: numba then adds no wrap-around
    of negative ones to each load.
    """
    values, index, _ = scratch
    wx, wy, corner = values[WX], values[WY], index[CORNER]
    one = np.uint64(1)
    below = np.uint64(width)
    for x in range(corner.shape[0]):
        i = np.uint64(corner[x])
        a, b = np.float64(flat[i]), np.float64(flat[i + one])
        c, d = np.float64(flat[i + below]), np.float64(flat[i + below + one])
        out[x] = _blend(a, b, c, d, wx[x], wy[x])


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _sample_grey(
    flat: np.ndarray, scratch: Row, width: int, levels: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """:func:`_sample` of an 8-bit image, each grey level read from ``levels`` (its float64).

    A table of 256 values stays in the first-level cache; reading it is faster here than both
    converting each byte and gathering into a scratch first.
    """
    values, index, _ = scratch
    wx, wy, corner = values[WX], values[WY], index[CORNER]
    one = np.uint64(1)
    below = np.uint64(width)
    for x in range(corner.shape[0]):
        i = np.uint64(corner[x])
        a, b = levels[np.uint64(flat[i])], levels[np.uint64(flat[i + one])]
        c, d = levels[np.uint64(flat[i + below])], levels[np.uint64(flat[i + below + one])]
        out[x] = _blend(a, b, c, d, wx[x], wy[x])


@njit(cache=True, nogil=True, error_model="numpy")
def motion_splat(
    source: np.ndarray,
    images: tuple[np.ndarray, np.ndarray],
    rt: np.ndarray,
    geo: np.ndarray,
    offset: float,
    photometric: float,
    zbuffer: np.ndarray,
    moving: np.ndarray,
    scratch: Row,
) -> None:  # pragma: no cover - compiled
    """The z-buffer of ``t + k`` (float32 disparities, largest = nearest) from the points of ``t``.

    Each point writes its predicted disparity into the four pixels of its bilinear support
    (``⌊x'⌋, ⌊x'⌋ + 1`` × ``⌊y'⌋, ⌊y'⌋ + 1``): a surface magnified up to 2× leaves no hole
    through which a point it hides would look visible. Points that fail the photometric check
    (``images``: left at ``t`` and ``t + k``, or 0×0) are marked in ``moving`` (written in full)
    and hide nothing: a car that drove away would otherwise hide the road it uncovered.

    Done as one write per point, at its support's corner ``(⌊x'⌋, ⌊y'⌋)``, then a 2×2 maximum
    filter (:func:`_support_maximum`): the maximum is exact, so this is the same z-buffer at a
    quarter of the scattered writes.
    """
    height, width = source.shape
    zbuffer[:] = -np.inf
    flat = zbuffer.reshape(-1)
    box = (0.0, np.float64(width - 1), 0.0, np.float64(height - 1))
    values, index, marks = scratch
    predicted, seen = values[PREDICTED], values[SAMPLED]
    corner, lands = index[CORNER], marks[LANDS]
    us = _columns(width, geo)
    src_image, tgt_image = images
    photo = src_image.shape[0] == height and tgt_image.shape[0] == height
    tgt_flat = tgt_image.reshape(-1)
    levels = np.arange(256.0)
    for y in range(height):
        _landing(source[y], us, y, rt, geo, offset, box, (height, width), scratch, False)
        flags = moving[y]
        if photo:
            _sample_grey(tgt_flat, scratch, width, levels, seen)
            src_row = src_image[y]
            for x in range(width):  # branch-free: whether a point moved is not predictable
                flags[x] = lands[x] & (abs(np.float64(src_row[x]) - seen[x]) > photometric)
        else:
            flags[:] = False
        for x in range(width):
            if lands[x] and not flags[x]:
                i = np.uint64(corner[x])
                flat[i] = max(flat[i], np.float32(predicted[x]))
    _support_maximum(zbuffer)


@njit(cache=True, nogil=True, error_model="numpy")
def _support_maximum(zbuffer: np.ndarray) -> None:  # pragma: no cover - compiled
    """In place: each pixel becomes the maximum of itself and its left, upper, upper-left pixel.

    A corner written at ``(x0, y0)`` so reaches ``x0 + 1`` and ``y0 + 1``. Row by row, each
    row's horizontal maximum kept before it is overwritten; every loop vectorises.
    """
    height, width = zbuffer.shape
    above = np.full(width, -np.inf, np.float32)
    here = np.empty(width, np.float32)
    for y in range(height):
        row = zbuffer[y]
        here[0] = row[0]
        for x in range(1, width):
            here[x] = max(row[x], row[x - 1])
        for x in range(width):
            row[x] = max(here[x], above[x])
        above, here = here, above


@njit(cache=True, nogil=True, error_model="numpy")
def motion_classify(
    source: tuple[np.ndarray, np.ndarray],
    target: tuple[np.ndarray, np.ndarray],
    rt: np.ndarray,
    geo: np.ndarray,
    offset: float,
    limits: np.ndarray,
    zbuffer: np.ndarray,
    moving: np.ndarray,
    cells: np.ndarray,
    thresholds: np.ndarray,
    sums: np.ndarray,
    maps: tuple[np.ndarray, np.ndarray, np.ndarray],
    scratch: Row,
) -> None:  # pragma: no cover - compiled
    """Every source pixel's status and residual; adds the sums of its cell (``cells`` < 0: none).

    ``source``/``target``: (disparity with NaN where missing, edge mask); ``zbuffer`` and
    ``moving`` from :func:`motion_splat`; ``limits``: (border margin px, occlusion tolerance px).
    ``maps``: the status (int8), disparity residual and depth residual (float32, NaN unless
    counted) of every pixel, written in full (maps of one row: rewritten for each row, when
    the caller keeps only the sums; ``cells`` of one row: the same cells for every row). Per
    row: vectorised geometry, bare gathers, one vectorised pass for the masks and residuals,
    the row's sums.
    """
    src, src_edges = source
    tgt, tgt_edges = target
    status_map, r_map, rz_map = maps
    height, width = src.shape
    fb, doffs = geo[3], geo[4]
    margin, tolerance = limits[0], limits[1]
    box = (margin, np.float64(width - 1) - margin, margin, np.float64(height - 1) - margin)
    values, index, marks = scratch
    ss, ws, predicted, nearest = values[S], values[W], values[PREDICTED], values[NEAREST]
    sampled = values[SAMPLED]
    near = index[NEAR]
    lands, tgt_edge = marks[LANDS], marks[TARGET_EDGE]
    us = _columns(width, geo)
    tgt_flat = tgt.reshape(-1)
    z_flat = zbuffer.reshape(-1)
    edges_flat = tgt_edges.reshape(-1)
    for y in range(height):
        _landing(src[y], us, y, rt, geo, offset, box, (height, width), scratch, True)
        _sample(tgt_flat, scratch, width, sampled)
        for x in range(width):  # unsigned: no wrap-around of negative indices
            i = np.uint64(near[x])
            nearest[x] = z_flat[i]
            tgt_edge[x] = edges_flat[i]
        edge_row = src_edges[y]
        moving_row = moving[y]
        kept = y if status_map.shape[0] == height else 0  # one row: the maps are not kept
        status_row = status_map[kept]
        r_row = r_map[kept]
        rz_row = rz_map[kept]
        for x in range(width):  # selects, last mask first: the first that applies wins
            observed = sampled[x] - offset
            seen = observed + doffs  # NaN: a support pixel is missing
            value = predicted[x]
            s = ss[x]
            status = MOVING if moving_row[x] else COUNTED
            status = EDGE if edge_row[x] | tgt_edge[x] else status
            status = MISSING_TARGET if not seen > 0.0 else status
            status = HIDDEN if nearest[x] > np.float64(np.float32(value)) + tolerance else status
            status = BORDER if not lands[x] else status
            status = MISSING if not s > 0.0 else status
            counted = status == COUNTED
            # depth at t + k minus the moved depth w/s, over one division
            rz = (fb * s - ws[x] * seen) / (seen * s)
            status_row[x] = status
            r_row[x] = observed - value if counted else np.nan
            rz_row[x] = rz if counted else np.nan
        cell_row = cells[y if cells.shape[0] == height else 0]  # one row: the same for every row
        _row_sums(status_row, r_row, rz_row, cell_row, thresholds, sums)


MASKED_CELLS = 4
"""Up to this many cells, a row's sums are one vectorised masked pass per cell."""


@njit(cache=True, nogil=True, fastmath=_FAST, error_model="numpy")
def _row_sums(
    status: np.ndarray,
    r: np.ndarray,
    rz: np.ndarray,
    cells: np.ndarray,
    thresholds: np.ndarray,
    sums: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Add one row's pixels to their cells (``cells`` < 0: none; ``r`` read where counted).

    A kernel of its own, with reassociation allowed so its sums vectorise; the geometry stays
    IEEE arithmetic. Up to :data:`MASKED_CELLS` cells, one pass per cell gives the status
    counts, the residual terms and the first three thresholds' counts (selects, no branches:
    a pixel that is not counted adds zeros; thresholds are ≥ 0, so 0 is never above one).
    """
    n_cells = sums.shape[0]
    if n_cells > MASKED_CELLS:
        for x in range(status.shape[0]):
            if cells[x] >= 0:
                _add(sums, cells[x], status[x], r[x], rz[x], thresholds)
        return
    limits = np.full(3 * ((thresholds.shape[0] + 2) // 3), np.inf)  # ∞: never exceeded
    limits[: thresholds.shape[0]] = thresholds
    t0, t1, t2 = limits[0], limits[1], limits[2]
    for cell in range(n_cells):
        c0 = c1 = c2 = c3 = c4 = c5 = c6 = b0 = b1 = b2 = np.int32(0)
        sum_abs = total = sum_sq = sum_abs_z = sum_sq_z = 0.0
        for x in range(status.shape[0]):
            code = np.int32(status[x]) if cells[x] == cell else np.int32(-1)
            c0 += code == COUNTED
            c1 += code == MISSING
            c2 += code == BORDER
            c3 += code == HIDDEN
            c4 += code == MISSING_TARGET
            c5 += code == EDGE
            c6 += code == MOVING
            counted = code == COUNTED
            value = np.float64(r[x]) if counted else 0.0
            value_z = np.float64(rz[x]) if counted else 0.0
            magnitude = abs(value)
            sum_abs += magnitude
            total += value
            sum_sq += value * value
            sum_abs_z += abs(value_z)
            sum_sq_z += value_z * value_z
            b0 += magnitude > t0
            b1 += magnitude > t1
            b2 += magnitude > t2
        totals = sums[cell]
        totals[COL_N] += c0 + c1 + c2 + c3 + c4 + c5 + c6  # one status per pixel: exact
        totals[COL_STATUS + COUNTED] += c0
        totals[COL_STATUS + MISSING] += c1
        totals[COL_STATUS + BORDER] += c2
        totals[COL_STATUS + HIDDEN] += c3
        totals[COL_STATUS + MISSING_TARGET] += c4
        totals[COL_STATUS + EDGE] += c5
        totals[COL_STATUS + MOVING] += c6
        totals[COL_SUM_ABS] += sum_abs
        totals[COL_SUM] += total
        totals[COL_SUM_SQ] += sum_sq
        totals[COL_SUM_ABS_Z] += sum_abs_z
        totals[COL_SUM_SQ_Z] += sum_sq_z
        bad = (b0, b1, b2)
        for i in range(min(3, thresholds.shape[0])):
            totals[COL_BAD + i] += bad[i]
        for first in range(3, thresholds.shape[0], 3):  # more thresholds: a pass per three
            more = _bad_counts(
                status, r, cells, cell, limits[first], limits[first + 1], limits[first + 2]
            )
            for i in range(min(3, thresholds.shape[0] - first)):
                totals[COL_BAD + first + i] += more[i]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _bad_counts(
    status: np.ndarray, r: np.ndarray, cells: np.ndarray, cell: int, t0: float, t1: float, t2: float
) -> tuple[int, int, int]:  # pragma: no cover - compiled
    """How many counted pixels of ``cell`` have ``|r|`` above each of three thresholds."""
    b0 = b1 = b2 = np.int32(0)
    for x in range(r.shape[0]):
        counted = (cells[x] == cell) & (status[x] == COUNTED)
        magnitude = abs(np.float64(r[x])) if counted else 0.0
        b0 += magnitude > t0
        b1 += magnitude > t1
        b2 += magnitude > t2
    return b0, b1, b2


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _add(
    sums: np.ndarray, cell: int, status: int, r: float, rz: float, thresholds: np.ndarray
) -> None:  # pragma: no cover - compiled
    """Add one pixel to its cell: its status count and, when counted (r not NaN), its terms.

    Branch-free: a pixel that is not counted adds zeros.
    """
    counted = status == COUNTED
    r = r if counted else 0.0
    rz = rz if counted else 0.0
    sums[cell, COL_N] += 1.0
    sums[cell, COL_STATUS + status] += 1.0
    magnitude = abs(r)
    sums[cell, COL_SUM_ABS] += magnitude
    sums[cell, COL_SUM] += r
    sums[cell, COL_SUM_SQ] += r * r
    sums[cell, COL_SUM_ABS_Z] += abs(rz)
    sums[cell, COL_SUM_SQ_Z] += rz * rz
    for i in range(thresholds.shape[0]):
        sums[cell, COL_BAD + i] += 1.0 if magnitude > thresholds[i] else 0.0


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _bilinear(image: np.ndarray, x0: int, y0: int, wx: float, wy: float) -> float:
    """Bilinear value at ``(x0 + wx, y0 + wy)`` (NaN when a support pixel is NaN)."""
    a, b = np.float64(image[y0, x0]), np.float64(image[y0, x0 + 1])
    c, d = np.float64(image[y0 + 1, x0]), np.float64(image[y0 + 1, x0 + 1])
    return _blend(a, b, c, d, wx, wy)


@njit(cache=True, nogil=True)
def positive_disparity(
    disparity: np.ndarray, out: np.ndarray, valid: np.ndarray
) -> None:  # pragma: no cover - compiled
    """Valid where finite and ``> 0``; ``out`` is the disparity there, NaN elsewhere (one pass)."""
    flat, flat_out, flat_valid = disparity.reshape(-1), out.reshape(-1), valid.reshape(-1)
    for i in range(flat.shape[0]):
        value = flat[i]
        ok = (value > 0) & (value < np.inf)  # NaN fails both
        flat_valid[i] = ok
        flat_out[i] = value if ok else np.float32(np.nan)


@njit(cache=True, nogil=True, error_model="numpy")
def flicker_spread(
    disparities: list[np.ndarray],
    images: list[np.ndarray],
    fb: float,
    doffs: float,
    photometric: float,
    mean: np.ndarray,
    maps: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:  # pragma: no cover - compiled
    """Per-pixel sample spread (``ddof = 1``) of disparity and depth over a window of frames.

    One pass over the frames (four rows at a time), shifted sums: each frame's deviation from
    the first frame's value (``δ``, and ``ε`` in depth) adds to ``Σδ`` and ``Σδ²``; the spread is
    ``√((Σδ² − (Σδ)²/n)/(n − 1))``. Shifting by a sample bounds the cancellation: the
    squared distance of the mean from any sample is at most ``(n − 1)·s²``, so the
    float64 sums lose at most ``log₂ n`` bits (plain sums of squares of disparities ~100 px
    with a spread of 0.01 px would lose 20). An unchanging pixel has every ``δ = 0``: a spread
    of exactly 0. Writes the window's ``mean`` disparity (NaN where a frame has no estimate),
    the status (missing in a frame, else moving when the intensity range over ``images``
    exceeds ``photometric``, else counted: edges come later from ``mean``) and the spreads
    (NaN unless counted). Every loop is element-wise over a row: it vectorises.
    """
    status_map, r_map, rz_map = maps
    frames = len(disparities)
    height, width = mean.shape
    with_images = len(images) == frames
    first = np.empty(width, np.float64)
    first_z = np.empty(width, np.float64)
    total = np.empty(width, np.float64)
    total_z = np.empty(width, np.float64)
    square = np.empty(width, np.float64)
    square_z = np.empty(width, np.float64)
    valid = np.empty(width, np.bool_)
    low = np.empty(width, np.uint8)  # grey levels as they are: 64 lanes a vector
    high = np.empty(width, np.uint8)
    per = 1.0 / frames  # reciprocals: multiplications in the per-pixel loop
    per_dof = 1.0 / (frames - 1)
    for y in range(height):
        row = disparities[0][y]
        for f in range(1, frames, 4):  # four frames' rows per pass: a quarter of the traffic
            # past the last frame, the first frame's row: its deviations are exactly 0
            r0 = disparities[f][y]
            r1 = disparities[f + 1 if f + 1 < frames else 0][y]
            r2 = disparities[f + 2 if f + 2 < frames else 0][y]
            r3 = disparities[f + 3 if f + 3 < frames else 0][y]
            fresh = f == 1  # the first pass starts the sums from the first frame's row
            for x in range(width):
                if fresh:
                    d = np.float64(row[x])
                    s = d + doffs
                    ok = s > 0.0
                    base = d if ok else 0.0
                    base_z = fb / s if ok else 0.0
                    first[x] = base
                    first_z[x] = base_z
                    before, t_d, t_z, q_d, q_z = ok, 0.0, 0.0, 0.0, 0.0
                else:
                    base, base_z = first[x], first_z[x]
                    before, t_d, t_z, q_d, q_z = (
                        valid[x],
                        total[x],
                        total_z[x],
                        square[x],
                        square_z[x],
                    )
                d0, d1 = np.float64(r0[x]), np.float64(r1[x])
                d2, d3 = np.float64(r2[x]), np.float64(r3[x])
                s0, s1, s2, s3 = d0 + doffs, d1 + doffs, d2 + doffs, d3 + doffs
                k0, k1, k2, k3 = s0 > 0.0, s1 > 0.0, s2 > 0.0, s3 > 0.0
                valid[x] = before & k0 & k1 & k2 & k3
                a0 = d0 - base if k0 else 0.0
                a1 = d1 - base if k1 else 0.0
                a2 = d2 - base if k2 else 0.0
                a3 = d3 - base if k3 else 0.0
                z0 = fb / s0 - base_z if k0 else 0.0
                z1 = fb / s1 - base_z if k1 else 0.0
                z2 = fb / s2 - base_z if k2 else 0.0
                z3 = fb / s3 - base_z if k3 else 0.0
                total[x] = t_d + ((a0 + a1) + (a2 + a3))
                total_z[x] = t_z + ((z0 + z1) + (z2 + z3))
                square[x] = q_d + ((a0 * a0 + a1 * a1) + (a2 * a2 + a3 * a3))
                square_z[x] = q_z + ((z0 * z0 + z1 * z1) + (z2 * z2 + z3 * z3))
        low[:] = 0  # no images: a range of 0, never moving
        high[:] = 0
        if with_images:
            low[:] = images[0][y]
            high[:] = images[0][y]
            for f in range(1, frames):
                grey = images[f][y]
                for x in range(width):
                    low[x] = min(low[x], grey[x])
                    high[x] = max(high[x], grey[x])
        mean_row, status_row, r_row, rz_row = mean[y], status_map[y], r_map[y], rz_map[y]
        for x in range(width):
            complete = valid[x]
            moving = np.float64(np.int32(high[x]) - np.int32(low[x])) > photometric
            # float32 square roots of the float64 variances: the maps are float32 anyway
            spread = np.sqrt(np.float32(max(square[x] - total[x] * total[x] * per, 0.0) * per_dof))
            spread_z = np.sqrt(
                np.float32(max(square_z[x] - total_z[x] * total_z[x] * per, 0.0) * per_dof)
            )
            mean_row[x] = np.float32(first[x] + total[x] * per) if complete else np.float32(np.nan)
            status_row[x] = MISSING if not complete else (MOVING if moving else COUNTED)
            counted = complete and not moving
            r_row[x] = spread if counted else np.float32(np.nan)
            rz_row[x] = spread_z if counted else np.float32(np.nan)


@njit(cache=True, nogil=True, error_model="numpy")
def flicker_sums(
    edges: np.ndarray,
    cells: np.ndarray,
    thresholds: np.ndarray,
    sums: np.ndarray,
    maps: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:  # pragma: no cover - compiled
    """Mark pixels near an edge of the mean map (before moving) and add every cell.

    Only the status changes: the spreads of pixels not counted are left as they are (the
    sums read them only where counted).
    """
    status_map, r_map, rz_map = maps
    height, width = edges.shape
    for y in range(height):
        edge_row, status_row, r_row, rz_row = edges[y], status_map[y], r_map[y], rz_map[y]
        for x in range(width):  # a select: it vectorises
            near = edge_row[x] & (status_row[x] != MISSING)
            status_row[x] = EDGE if near else status_row[x]
        cell_row = cells[y if cells.shape[0] == height else 0]  # one row: the same for every row
        _row_sums(status_row, r_row, rz_row, cell_row, thresholds, sums)
