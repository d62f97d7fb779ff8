"""Compiled loops of the temporal measures: ego-motion reprojection (z-buffer, masks, sums).

Kept apart from :mod:`dispeval_ros.core.egomotion` (records, checks, the offset fit) because
these are the only loops that touch every pixel. Geometry, in the left rectified camera at
``t``: a pixel ``(x, y)`` with disparity ``e`` and offset ``b`` has depth ``Z = f·B/(e − b +
doffs)`` and the point ``P = Z·((x − cx)/f, (y − cy)/f, 1)``; ``Q = R·P + T`` is that point in
the camera at ``t + k``, where it lands at ``(cx + f·Qx/Qz, cy + f·Qy/Qz)`` with the
disparity ``f·B/Qz − doffs``. ``rt`` is the 3×4 ``[R | T]``; ``geo`` is ``(f, cx, cy, f·B,
doffs)``.
"""

from __future__ import annotations

import numpy as np

from dispeval_ros.core.kernels._jit import njit

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
    y: int,
    rt: np.ndarray,
    geo: np.ndarray,
    offset: float,
    box: tuple[float, float, float, float],
    out: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:  # pragma: no cover - compiled
    """Landing ``(x', y')``, predicted disparity, ``Qz`` and "lands in ``box``" of one row.

    Branch-free, so it vectorises: a missing estimate (NaN), no depth (``s ≤ 0``) or a point
    behind the camera fail the comparisons and land nowhere. ``box`` is (x_lo, x_hi, y_lo,
    y_hi) of the landings kept.
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
        u = (x - cx) / f
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


Row = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def row_buffers(width: int) -> Row:
    """Scratch of :func:`_row_geometry`: x', y', predicted disparity, Qz, lands."""
    held = [np.empty(width, np.float64) for _ in range(4)]
    return (held[0], held[1], held[2], held[3], np.empty(width, np.bool_))


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
    scratch: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:  # pragma: no cover - compiled
    """The z-buffer of ``t + k`` (float32 disparities, largest = nearest) from the points of ``t``.

    Each point writes its predicted disparity into the four pixels of its bilinear support
    (``⌊x'⌋, ⌊x'⌋ + 1`` × ``⌊y'⌋, ⌊y'⌋ + 1``): a surface magnified up to 2× leaves no hole
    through which a point it hides would look visible. Points that fail the photometric check
    (``images``: left at ``t`` and ``t + k``, or 0×0) are marked in ``moving`` (written in full)
    and hide nothing: a car that drove away would otherwise hide the road it uncovered.
    """
    height, width = source.shape
    zbuffer[:] = -np.inf
    moving[:] = False
    box = (0.0, np.float64(width - 1), 0.0, np.float64(height - 1))
    xs, ys, predicted, _, lands = scratch
    src_image, tgt_image = images
    photo = src_image.shape[0] == height and tgt_image.shape[0] == height
    for y in range(height):
        _row_geometry(source[y], y, rt, geo, offset, box, scratch)
        for x in range(width):
            if not lands[x]:
                continue
            value = np.float32(predicted[x])
            x0 = min(int(xs[x]), width - 2)
            y0 = min(int(ys[x]), height - 2)
            if photo:
                seen = _bilinear(tgt_image, x0, y0, xs[x] - x0, ys[x] - y0)
                if abs(np.float64(src_image[y, x]) - seen) > photometric:
                    moving[y, x] = True
                    continue
            zbuffer[y0, x0] = max(zbuffer[y0, x0], value)
            zbuffer[y0, x0 + 1] = max(zbuffer[y0, x0 + 1], value)
            zbuffer[y0 + 1, x0] = max(zbuffer[y0 + 1, x0], value)
            zbuffer[y0 + 1, x0 + 1] = max(zbuffer[y0 + 1, x0 + 1], value)


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
    scratch: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:  # pragma: no cover - compiled
    """Every source pixel's status and residual; adds the sums of its cell (``cells`` < 0: none).

    ``source``/``target``: (disparity with NaN where missing, edge mask); ``zbuffer`` and
    ``moving`` from :func:`motion_splat`; ``limits``: (border margin px, occlusion tolerance px).
    ``maps``: the status (int8), disparity residual and depth residual (float32, NaN unless
    counted) of every pixel, written in full.
    """
    src, src_edges = source
    tgt, tgt_edges = target
    status_map, r_map, rz_map = maps
    height, width = src.shape
    fb, doffs = geo[3], geo[4]
    margin, tolerance = limits[0], limits[1]
    box = (margin, np.float64(width - 1) - margin, margin, np.float64(height - 1) - margin)
    xs, ys, predicted, depth, lands = scratch
    for y in range(height):
        row = src[y]
        _row_geometry(row, y, rt, geo, offset, box, scratch)
        for x in range(width):
            status = COUNTED
            r = np.nan
            rz = np.nan
            if not np.float64(row[x]) - offset + doffs > 0.0:
                status = MISSING
            elif not lands[x]:
                status = BORDER
            else:
                xp = xs[x]
                yp = ys[x]
                x0 = min(int(xp), width - 2)
                y0 = min(int(yp), height - 2)
                wx = xp - x0
                wy = yp - y0
                row_near = int(yp + 0.5)
                column_near = int(xp + 0.5)
                nearest = zbuffer[row_near, column_near]
                observed = _bilinear(tgt, x0, y0, wx, wy) - offset
                if np.float64(nearest) > np.float64(np.float32(predicted[x])) + tolerance:
                    status = HIDDEN
                elif not observed + doffs > 0.0:  # NaN: a support pixel is missing
                    status = MISSING_TARGET
                elif src_edges[y, x] or tgt_edges[row_near, column_near]:
                    status = EDGE
                elif moving[y, x]:
                    status = MOVING
                else:
                    r = observed - predicted[x]
                    rz = fb / (observed + doffs) - depth[x]
            status_map[y, x] = status
            r_map[y, x] = r
            rz_map[y, x] = rz
            cell = cells[y, x]
            if cell >= 0:
                _add(sums, cell, status, r, rz, thresholds)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _add(
    sums: np.ndarray, cell: int, status: int, r: float, rz: float, thresholds: np.ndarray
) -> None:  # pragma: no cover - compiled
    """Add one pixel to its cell: its status count and, when counted, its residual terms."""
    sums[cell, COL_N] += 1.0
    sums[cell, COL_STATUS + status] += 1.0
    if status == COUNTED:
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


@njit(cache=True, nogil=True, error_model="numpy")
def offset_terms(
    source: np.ndarray,
    target: np.ndarray,
    rt: np.ndarray,
    geo: np.ndarray,
    offset: float,
    status_map: np.ndarray,
    inlier: float,
    stride: int,
    residuals: np.ndarray,
) -> tuple[float, float, float, int]:  # pragma: no cover - compiled
    """Gauss-Newton terms ``(Σ J·r, Σ J², n)`` and the number of residuals written.

    Over every ``stride``-th counted pixel of every ``stride``-th row with ``|r| ≤ inlier``.
    ``r(b)`` is the residual with both estimates shifted by ``−b``, ``J = dr/db`` (analytic:
    the depth, the landing and the bilinear value all move with ``b``). ``residuals`` gets
    every finite ``r`` of those pixels, inliers or not (for the robust scale).
    """
    height, width = source.shape
    f, cx, cy, fb, doffs = geo[0], geo[1], geo[2], geo[3], geo[4]
    last_x = np.float64(width - 1)
    last_y = np.float64(height - 1)
    jr = 0.0
    jj = 0.0
    n = 0.0
    written = 0
    for y in range(0, height, stride):
        v = (y - cy) / f
        bx = rt[0, 1] * v + rt[0, 2]
        by = rt[1, 1] * v + rt[1, 2]
        bz = rt[2, 1] * v + rt[2, 2]
        for x in range(0, width, stride):
            if status_map[y, x] != COUNTED:
                continue
            s = np.float64(source[y, x]) - offset + doffs
            z = fb / s
            u = (x - cx) / f
            ax = rt[0, 0] * u + bx
            ay = rt[1, 0] * u + by
            az = rt[2, 0] * u + bz
            qx = z * ax + rt[0, 3]
            qy = z * ay + rt[1, 3]
            qz = z * az + rt[2, 3]
            xp = cx + f * qx / qz
            yp = cy + f * qy / qz
            if not (s > 0.0 and qz > 0.0 and 0.0 <= xp <= last_x and 0.0 <= yp <= last_y):
                continue
            x0 = min(int(xp), width - 2)
            y0 = min(int(yp), height - 2)
            wx = xp - x0
            wy = yp - y0
            observed = _bilinear(target, x0, y0, wx, wy) - offset
            r = observed - (fb / qz - doffs)
            if not abs(r) < np.inf:  # a support pixel is missing
                continue
            residuals[written] = r
            written += 1
            if not abs(r) <= inlier:
                continue
            p00 = np.float64(target[y0, x0])
            p01 = np.float64(target[y0, x0 + 1])
            p10 = np.float64(target[y0 + 1, x0])
            p11 = np.float64(target[y0 + 1, x0 + 1])
            dz = z * z / fb
            gx = (1.0 - wy) * (p01 - p00) + wy * (p11 - p10)
            gy = (1.0 - wx) * (p10 - p00) + wx * (p11 - p01)
            dxp = f * (ax * qz - qx * az) / (qz * qz) * dz
            dyp = f * (ay * qz - qy * az) / (qz * qz) * dz
            j = gx * dxp + gy * dyp - 1.0 + fb * az * dz / (qz * qz)
            jr += j * r
            jj += j * j
            n += 1.0
    return jr, jj, n, written


@njit(cache=True, nogil=True, error_model="numpy")
def flicker_add(
    disparity: np.ndarray,
    image: np.ndarray,
    fb: float,
    doffs: float,
    state: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    count: float,
) -> None:  # pragma: no cover - compiled
    """Add frame number ``count`` (1-based) to a window's per-pixel state (Welford's update).

    ``state``: missing in some frame (bool), mean and M2 of the disparity and of the depth
    (float64), and the intensity range (int16 min and max as a (2, H, W) array; untouched
    when ``image`` is 0×0).
    """
    missing, mean, m2, mean_z, m2_z, grey = state
    height, width = disparity.shape
    with_image = image.shape[0] == height
    for y in range(height):
        for x in range(width):
            d = np.float64(disparity[y, x])
            s = d + doffs
            if not s > 0.0:
                missing[y, x] = True
            else:
                z = fb / s
                delta = d - mean[y, x]
                mean[y, x] += delta / count
                m2[y, x] += delta * (d - mean[y, x])
                delta_z = z - mean_z[y, x]
                mean_z[y, x] += delta_z / count
                m2_z[y, x] += delta_z * (z - mean_z[y, x])
            if with_image:
                g = np.int16(image[y, x])
                grey[0, y, x] = min(grey[0, y, x], g)
                grey[1, y, x] = max(grey[1, y, x], g)


@njit(cache=True, nogil=True, error_model="numpy")
def flicker_sums(
    state: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    edges: np.ndarray,
    frames: float,
    photometric: float,
    cells: np.ndarray,
    thresholds: np.ndarray,
    sums: np.ndarray,
    maps: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:  # pragma: no cover - compiled
    """Per-pixel sample spread (``ddof = 1``) of a window and the sums of each cell.

    Masks in order: missing in any frame, ``edges`` (of the window's mean map), intensity
    range above ``photometric`` (moving; without images the range is negative).
    """
    missing, _, m2, _, m2_z, grey = state
    status_map, r_map, rz_map = maps
    height, width = missing.shape
    for y in range(height):
        for x in range(width):
            status = COUNTED
            r = np.nan
            rz = np.nan
            if missing[y, x]:
                status = MISSING
            elif edges[y, x]:
                status = EDGE
            elif np.float64(grey[1, y, x]) - np.float64(grey[0, y, x]) > photometric:
                status = MOVING
            else:
                r = np.sqrt(m2[y, x] / (frames - 1.0))
                rz = np.sqrt(m2_z[y, x] / (frames - 1.0))
            status_map[y, x] = status
            r_map[y, x] = r
            rz_map[y, x] = rz
            cell = cells[y, x]
            if cell >= 0:
                _add(sums, cell, status, r, rz, thresholds)
