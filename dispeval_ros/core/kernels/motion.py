"""Compiled loops of the temporal measures: ego-motion reprojection (z-buffer, masks, sums).

Kept apart from :mod:`dispeval_ros.core.egomotion` (records, checks, the offset fit) because
these are the only loops that touch every pixel. Geometry, in the left rectified camera at
``t``: a pixel ``(x, y)`` with disparity ``e`` and offset ``b`` has depth ``Z = f·B/(e − b +
doffs)`` and the point ``P = Z·((x − cx)/f, (y − cy)/f, 1)``; ``Q = R·P + T`` is that point in
the camera at ``t + k``, where it lands at ``(cx + f·Qx/Qz, cy + f·Qy/Qz)`` with the
disparity ``f·B/Qz − doffs``. ``rt`` is the 3×4 ``[R | T]``; ``geo`` is ``(f, cx, cy, f·B,
doffs)``. The offset fit's loops (a sparse grid) are in :mod:`.motion_fit`.

Every loop keeps the exact IEEE operations of the definition (no fast-math outside the sums),
so restructuring for speed changes no result: per row, vectorised passes for the geometry and
the masks, bare scalar loads for the gathers (numba's wrap-around of negative indices avoided
by unsigned ones), one scattered write per point into the z-buffer.
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
def _row_geometry(
    row: np.ndarray,
    us: np.ndarray,
    y: int,
    rt: np.ndarray,
    geo: np.ndarray,
    offset: float,
    box: tuple[float, float, float, float],
    out: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:  # pragma: no cover - compiled
    """Landing ``(x', y')``, predicted disparity, ``Qz`` and "lands in ``box``" of one row.

    Branch-free, so it vectorises: a missing estimate (NaN), no depth (``s ≤ 0``) or a point
    behind the camera fail the comparisons and land nowhere. ``us``: ``(x − cx)/f`` of every
    column (:func:`_columns`: one division per column, not per pixel). ``box`` is (x_lo, x_hi,
    y_lo, y_hi) of the landings kept.
    """
    xs, ys, predicted, depth, lands = out
    f, cx, cy, fb, doffs = geo[0], geo[1], geo[2], geo[3], geo[4]
    v = (y - cy) / f
    bx = rt[0, 1] * v + rt[0, 2]
    by = rt[1, 1] * v + rt[1, 2]
    bz = rt[2, 1] * v + rt[2, 2]
    x_lo, x_hi, y_lo, y_hi = box
    for x in range(row.shape[0]):
        s = np.float64(row[x]) - offset + doffs
        z = fb / s
        u = us[x]
        qz = z * (rt[2, 0] * u + bz) + rt[2, 3]
        inverse = 1.0 / qz
        xp = cx + f * (z * (rt[0, 0] * u + bx) + rt[0, 3]) * inverse
        yp = cy + f * (z * (rt[1, 0] * u + by) + rt[1, 3]) * inverse
        ok = (s > 0.0) & (qz > 0.0) & (xp >= x_lo) & (xp <= x_hi) & (yp >= y_lo) & (yp <= y_hi)
        xs[x] = xp if ok else 0.0
        ys[x] = yp if ok else 0.0
        predicted[x] = fb * inverse - doffs
        depth[x] = qz
        lands[x] = ok


Row = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
XS, YS, PREDICTED, DEPTH, WX, WY, NEAREST = 0, 1, 2, 3, 4, 5, 6
"""Rows of the float64 row scratch."""
CORNER, NEAR = 0, 1
"""Rows of the int64 row scratch: flat index of the support's corner and of the nearest pixel."""
LANDS, TARGET_EDGE = 0, 1
"""Rows of the bool row scratch."""


def row_buffers(width: int) -> Row:
    """Scratch of one row: float64 rows, a support's values, int64 flat indices, bool rows.

    A bilinear support's four values are float32: exact for a disparity or a grey level.
    """
    return (
        np.empty((NEAREST + 1, width), np.float64),
        np.empty((4, width), np.float32),
        np.empty((2, width), np.int64),
        np.empty((2, width), np.bool_),
    )


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _columns(width: int, geo: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """``u = (x − cx)/f`` of every column, the same IEEE operations as per pixel."""
    us = np.empty(width, np.float64)
    for x in range(width):
        us[x] = (x - geo[1]) / geo[0]
    return us


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
) -> None:  # pragma: no cover - compiled
    """:func:`_row_geometry` of one row, then each landing's support corner and nearest pixel.

    Vectorised passes only, so the gathers that follow (:func:`_gather`) are bare loads.
    """
    values, _, index, marks = scratch
    xs, ys, wx, wy = values[XS], values[YS], values[WX], values[WY]
    _row_geometry(
        row, us, y, rt, geo, offset, box, (xs, ys, values[PREDICTED], values[DEPTH], marks[LANDS])
    )
    height, width = shape
    corner, near = index[CORNER], index[NEAR]
    for x in range(row.shape[0]):  # 0 where the point lands nowhere: every gather stays inside
        x0 = min(int(xs[x]), width - 2)
        y0 = min(int(ys[x]), height - 2)
        wx[x] = xs[x] - x0
        wy[x] = ys[x] - y0
        corner[x] = y0 * width + x0
        near[x] = int(ys[x] + 0.5) * width + int(xs[x] + 0.5)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _gather(
    flat: np.ndarray, corner: np.ndarray, width: int, quad: np.ndarray
) -> None:  # pragma: no cover - compiled
    """The four values of each bilinear support (``flat``: an image as one row).

    Unsigned indices: numba then adds no wrap-around of negative ones to each load.
    """
    one = np.uint64(1)
    below = np.uint64(width)
    for x in range(corner.shape[0]):
        i = np.uint64(corner[x])
        quad[0, x] = flat[i]
        quad[1, x] = flat[i + one]
        quad[2, x] = flat[i + below]
        quad[3, x] = flat[i + below + one]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _lerp(quad: np.ndarray, wx: np.ndarray, wy: np.ndarray, x: int) -> float:
    """:func:`_bilinear` of gathered values (the same operations, so the same result)."""
    a, b = np.float64(quad[0, x]), np.float64(quad[1, x])
    c, d = np.float64(quad[2, x]), np.float64(quad[3, x])
    top = a + wx[x] * (b - a)
    return top + wy[x] * (c + wx[x] * (d - c) - top)


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
    values, quad, index, marks = scratch
    predicted, wx, wy = values[PREDICTED], values[WX], values[WY]
    corner, lands = index[CORNER], marks[LANDS]
    us = _columns(width, geo)
    src_image, tgt_image = images
    photo = src_image.shape[0] == height and tgt_image.shape[0] == height
    tgt_flat = tgt_image.reshape(-1)
    for y in range(height):
        _landing(source[y], us, y, rt, geo, offset, box, (height, width), scratch)
        flags = moving[y]
        if photo:
            _gather(tgt_flat, corner, width, quad)
            src_row = src_image[y]
            for x in range(width):  # branch-free: whether a point moved is not predictable
                seen = _lerp(quad, wx, wy, x)
                flags[x] = lands[x] & (abs(np.float64(src_row[x]) - seen) > photometric)
        else:
            flags[:] = False
        for x in range(width):
            if lands[x] and not flags[x]:
                i = corner[x]
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
    counted) of every pixel, written in full. Per row: vectorised geometry, bare gathers, one
    vectorised pass for the masks and residuals, the row's sums.
    """
    src, src_edges = source
    tgt, tgt_edges = target
    status_map, r_map, rz_map = maps
    height, width = src.shape
    fb, doffs = geo[3], geo[4]
    margin, tolerance = limits[0], limits[1]
    box = (margin, np.float64(width - 1) - margin, margin, np.float64(height - 1) - margin)
    values, quad, index, marks = scratch
    predicted, depth, nearest = values[PREDICTED], values[DEPTH], values[NEAREST]
    wx, wy = values[WX], values[WY]
    corner, near = index[CORNER], index[NEAR]
    lands, tgt_edge = marks[LANDS], marks[TARGET_EDGE]
    us = _columns(width, geo)
    tgt_flat = tgt.reshape(-1)
    z_flat = zbuffer.reshape(-1)
    edges_flat = tgt_edges.reshape(-1)
    for y in range(height):
        row = src[y]
        _landing(row, us, y, rt, geo, offset, box, (height, width), scratch)
        _gather(tgt_flat, corner, width, quad)
        for x in range(width):
            i = near[x]
            nearest[x] = z_flat[i]
            tgt_edge[x] = edges_flat[i]
        edge_row = src_edges[y]
        moving_row = moving[y]
        status_row = status_map[y]
        r_row = r_map[y]
        rz_row = rz_map[y]
        for x in range(width):  # branch-free: masks are not predictable
            observed = _lerp(quad, wx, wy, x) - offset
            value = predicted[x]
            hidden = nearest[x] > np.float64(np.float32(value)) + tolerance
            edge = edge_row[x] | tgt_edge[x]
            status = (
                MISSING
                if not np.float64(row[x]) - offset + doffs > 0.0
                else BORDER
                if not lands[x]
                else HIDDEN
                if hidden
                else MISSING_TARGET
                if not observed + doffs > 0.0  # NaN: a support pixel is missing
                else EDGE
                if edge
                else MOVING
                if moving_row[x]
                else COUNTED
            )
            counted = status == COUNTED
            r = observed - value if counted else np.nan
            rz = fb / (observed + doffs) - depth[x] if counted else np.nan
            status_row[x] = status
            r_row[x] = r
            rz_row[x] = rz
        _row_sums(status_row, r_row, rz_row, cells[y], thresholds, sums)


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
    """Add one row's pixels to their cells (``cells`` < 0: none; ``r`` NaN unless counted).

    A kernel of its own, with reassociation allowed so its sums vectorise; the geometry stays
    exact IEEE arithmetic (numpy re-computes it bit for bit).
    """
    n_cells = sums.shape[0]
    if n_cells > MASKED_CELLS:
        for x in range(status.shape[0]):
            if cells[x] >= 0:
                _add(sums, cells[x], status[x], r[x], rz[x], thresholds)
        return
    for cell in range(n_cells):
        by_status = _status_counts(status, cells, cell)
        n = by_status.sum()  # each pixel of the cell has one status: whole numbers, exact
        sum_abs = total = sum_sq = sum_abs_z = sum_sq_z = 0.0
        for x in range(status.shape[0]):  # residual terms: vectorises (selects, no branches)
            counted = (cells[x] == cell) & (status[x] == COUNTED)
            value = np.float64(r[x]) if counted else 0.0
            value_z = np.float64(rz[x]) if counted else 0.0
            sum_abs += abs(value)
            total += value
            sum_sq += value * value
            sum_abs_z += abs(value_z)
            sum_sq_z += value_z * value_z
        totals = sums[cell]
        totals[COL_N] += n
        for k in range(STATUSES):
            totals[COL_STATUS + k] += by_status[k]
        totals[COL_SUM_ABS] += sum_abs
        totals[COL_SUM] += total
        totals[COL_SUM_SQ] += sum_sq
        totals[COL_SUM_ABS_Z] += sum_abs_z
        totals[COL_SUM_SQ_Z] += sum_sq_z
        for i in range(thresholds.shape[0]):
            limit = thresholds[i]
            bad = 0.0
            for x in range(status.shape[0]):  # NaN (not counted) is never above a threshold
                bad += 1.0 if (cells[x] == cell) & (abs(np.float64(r[x])) > limit) else 0.0
            totals[COL_BAD + i] += bad


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _status_counts(
    status: np.ndarray, cells: np.ndarray, cell: int
) -> np.ndarray:  # pragma: no cover - compiled
    """How many pixels of ``cell`` have each status: seven counters, compared, no scatter.

    A scatter into seven counters stalls on its own stores (a run of one status adds to one
    counter); whole-number counts are exact in any order.
    """
    c0 = c1 = c2 = c3 = c4 = c5 = c6 = 0
    for x in range(status.shape[0]):
        code = np.int64(status[x]) if cells[x] == cell else np.int64(-1)
        c0 += code == COUNTED
        c1 += code == MISSING
        c2 += code == BORDER
        c3 += code == HIDDEN
        c4 += code == MISSING_TARGET
        c5 += code == EDGE
        c6 += code == MOVING
    out = np.empty(STATUSES, np.float64)
    out[COUNTED], out[MISSING], out[BORDER], out[HIDDEN] = c0, c1, c2, c3
    out[MISSING_TARGET], out[EDGE], out[MOVING] = c4, c5, c6
    return out


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
    a = np.float64(image[y0, x0])
    b = np.float64(image[y0, x0 + 1])
    c = np.float64(image[y0 + 1, x0])
    d = np.float64(image[y0 + 1, x0 + 1])
    top = a + wx * (b - a)
    return top + wy * (c + wx * (d - c) - top)


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

    Row by row, each frame's row read twice from cache (mean, then squared deviations: no
    cancellation), every loop a vectorised pass. Writes the window's ``mean`` disparity
    (NaN where a frame has no estimate), the status (missing in a frame, else moving when the
    intensity range over ``images`` exceeds ``photometric``, else counted: edges come later
    from ``mean``) and the spreads (NaN unless counted). The loops are element-wise: they
    vectorise without reassociation, so an unchanging pixel has a spread of exactly 0.
    """
    status_map, r_map, rz_map = maps
    frames = len(disparities)
    height, width = mean.shape
    with_images = len(images) == frames
    total = np.empty(width, np.float64)
    total_z = np.empty(width, np.float64)
    square = np.empty(width, np.float64)
    square_z = np.empty(width, np.float64)
    valid = np.empty(width, np.float64)
    values = np.empty((frames, width), np.float64)
    depths = np.empty((frames, width), np.float64)
    low = np.empty(width, np.int32)
    high = np.empty(width, np.int32)
    for y in range(height):
        total[:] = 0.0
        total_z[:] = 0.0
        valid[:] = 0.0
        for f in range(frames):  # each frame's row once: values, depths and their totals
            row = disparities[f][y]
            d_row = values[f]
            z_row = depths[f]
            for x in range(width):
                d = np.float64(row[x])
                s = d + doffs
                ok = s > 0.0
                d_row[x] = d if ok else 0.0
                z_row[x] = fb / s if ok else 0.0
                valid[x] += 1.0 if ok else 0.0
                total[x] += d_row[x]
                total_z[x] += z_row[x]
        for x in range(width):
            total[x] /= frames
            total_z[x] /= frames
        square[:] = 0.0
        square_z[:] = 0.0
        for f in range(frames):  # squared deviations from the mean: no cancellation
            d_row = values[f]
            z_row = depths[f]
            for x in range(width):
                deviation = d_row[x] - total[x]
                deviation_z = z_row[x] - total_z[x]
                square[x] += deviation * deviation
                square_z[x] += deviation_z * deviation_z
        low[:] = 256
        high[:] = -1
        if with_images:
            for f in range(frames):
                grey = images[f][y]
                for x in range(width):
                    low[x] = min(low[x], np.int32(grey[x]))
                    high[x] = max(high[x], np.int32(grey[x]))
        for x in range(width):  # float64 only, apart from the selects below: vectorises
            square[x] = np.sqrt(square[x] / (frames - 1))
            square_z[x] = np.sqrt(square_z[x] / (frames - 1))
        mean_row, status_row, r_row, rz_row = mean[y], status_map[y], r_map[y], rz_map[y]
        for x in range(width):
            complete = valid[x] == frames
            moving = np.float64(high[x] - low[x]) > photometric
            mean_row[x] = np.float32(total[x]) if complete else np.float32(np.nan)
            status_row[x] = MISSING if not complete else (MOVING if moving else COUNTED)
            counted = complete and not moving
            r_row[x] = square[x] if counted else np.nan
            rz_row[x] = square_z[x] if counted else np.nan


@njit(cache=True, nogil=True, error_model="numpy")
def flicker_sums(
    edges: np.ndarray,
    cells: np.ndarray,
    thresholds: np.ndarray,
    sums: np.ndarray,
    maps: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:  # pragma: no cover - compiled
    """Mark counted pixels near an edge of the mean map (before moving) and add every cell."""
    status_map, r_map, rz_map = maps
    height, width = edges.shape
    for y in range(height):
        for x in range(width):
            if edges[y, x] and status_map[y, x] != MISSING:
                status_map[y, x] = EDGE
                r_map[y, x] = np.nan
                rz_map[y, x] = np.nan
        _row_sums(status_map[y], r_map[y], rz_map[y], cells[y], thresholds, sums)
