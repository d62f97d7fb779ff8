"""Compiled loops of the ego-motion residual's offset fit: sparse samples, residuals, L1 steps.

Apart from :mod:`dispeval_ros.core.kernels.motion` (the loops over every pixel) because the fit
reads a sparse grid only; the geometry is the same (see there).
"""

from __future__ import annotations

import numpy as np

from dispeval_ros.core.kernels._jit import njit
from dispeval_ros.core.kernels.motion import _bilinear, _blend, _columns


@njit(cache=True, nogil=True)
def fit_samples(
    source: np.ndarray, edges: np.ndarray, stride: int
) -> np.ndarray:  # pragma: no cover
    """The pixels the offset fit may use, as ``(y, x)`` rows (int32, N × 2).

    Every ``stride``-th pixel of every ``stride``-th row with an estimate and no depth edge.
    """
    height, width = source.shape
    out = np.empty(
        ((height + stride - 1) // stride * ((width + stride - 1) // stride), 2), np.int32
    )
    n = 0
    for y in range(0, height, stride):
        for x in range(0, width, stride):
            if source[y, x] > -np.inf and not edges[y, x]:  # NaN: missing
                out[n, 0] = y
                out[n, 1] = x
                n += 1
    return out[:n]


@njit(cache=True, nogil=True, error_model="numpy")
def offset_residuals(
    source: np.ndarray,
    target: tuple[np.ndarray, np.ndarray],
    images: tuple[np.ndarray, np.ndarray],
    samples: np.ndarray,
    rt: np.ndarray,
    geo: np.ndarray,
    offset: float,
    photometric: float,
    out: tuple[np.ndarray, np.ndarray],
) -> int:  # pragma: no cover - compiled
    """Residuals ``r(b)`` and slopes ``dr/db`` of the samples the offset fit uses; how many.

    The ``samples`` (:func:`fit_samples`) that land in the image on a support without a
    hole or a depth edge of ``target`` (disparity, edges) and pass the photometric check
    (``images``, or 0×0); no z-buffer (hidden points are outliers the median ignores).
    ``r(b)`` is the residual with both estimates shifted by ``−b``; ``dr/db`` is analytic (the
    depth, the landing and the bilinear value all move with ``b``).
    """
    height, width = source.shape
    f, cx, cy, fb, doffs = geo[0], geo[1], geo[2], geo[3], geo[4]
    tgt, tgt_edges = target
    src_image, tgt_image = images
    residuals, slopes = out
    photo = src_image.shape[0] == height and tgt_image.shape[0] == height
    last_x = np.float64(width - 1)
    last_y = np.float64(height - 1)
    us = _columns(width, geo)  # (x − cx)/f per column and (y − cy)/f per row: once, not per pixel
    vs = np.empty(height, np.float64)
    for y in range(height):
        vs[y] = (y - cy) / f
    written = 0
    for i in range(samples.shape[0]):
        y = samples[i, 0]
        x = samples[i, 1]
        s = np.float64(source[y, x]) - offset + doffs
        z = fb / s
        u = us[x]
        v = vs[y]
        ax = rt[0, 0] * u + rt[0, 1] * v + rt[0, 2]
        ay = rt[1, 0] * u + rt[1, 1] * v + rt[1, 2]
        az = rt[2, 0] * u + rt[2, 1] * v + rt[2, 2]
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
        p00 = np.float64(tgt[y0, x0])  # the support, loaded once for the value and slopes
        p01 = np.float64(tgt[y0, x0 + 1])
        p10 = np.float64(tgt[y0 + 1, x0])
        p11 = np.float64(tgt[y0 + 1, x0 + 1])
        r = _blend(p00, p01, p10, p11, wx, wy) - offset - (fb / qz - doffs)
        if not abs(r) < np.inf or tgt_edges[int(yp + 0.5), int(xp + 0.5)]:
            continue
        if photo and (
            abs(np.float64(src_image[y, x]) - _bilinear(tgt_image, x0, y0, wx, wy)) > photometric
        ):
            continue
        dz = z * z / fb
        gx = (1.0 - wy) * (p01 - p00) + wy * (p11 - p10)
        gy = (1.0 - wx) * (p10 - p00) + wx * (p11 - p01)
        dxp = f * (ax * qz - qx * az) / (qz * qz) * dz
        dyp = f * (ay * qz - qy * az) / (qz * qz) * dz
        residuals[written] = r
        slopes[written] = gx * dxp + gy * dyp + fb * az * dz / (qz * qz) - 1.0
        written += 1
    return written


@njit(cache=True, nogil=True)
def l1_candidates(
    residuals: np.ndarray, slopes: np.ndarray, floor: float, out: tuple[np.ndarray, np.ndarray]
) -> tuple[int, float]:  # pragma: no cover - compiled
    """The inliers' steps ``−r/J`` and weights ``|J|`` (into ``out``): how many, their total.

    Inliers: ``|r − median| ≤ max(floor, 4 · 1.4826 · MAD)`` (a moving car's residual of
    tens of px is no evidence about the offset). The step ``Δ`` minimising ``Σ |r + J·Δ|`` is
    the weighted median of the steps (:func:`weighted_median`): pixels where the offset changes
    the residual most decide it. The sort between the two is numpy's (vectorised; numba's is
    several times slower on a few thousand values).
    """
    n = residuals.shape[0]
    centre = np.median(residuals)
    bound = max(floor, 4.0 * 1.4826 * np.median(np.abs(residuals - centre)))
    steps, weights = out
    kept = 0
    total = 0.0
    for i in range(n):
        weight = abs(slopes[i])
        if weight > 0.0 and abs(residuals[i] - centre) <= bound:
            steps[kept] = -residuals[i] / slopes[i]
            weights[kept] = weight
            total += weight
            kept += 1
    return kept, total


@njit(cache=True, nogil=True)
def weighted_median(
    steps: np.ndarray, weights: np.ndarray, order: np.ndarray, total: float
) -> tuple[float, float]:  # pragma: no cover - compiled
    """The step where the running weight in ``order`` first reaches half, and the mean weight.

    ``steps``/``weights``: the ``kept`` candidates of :func:`l1_candidates`, ``order`` their
    ascending order; returns ``(0, 0)`` when there are none.
    """
    kept = order.shape[0]
    if kept == 0:
        return 0.0, 0.0
    half = 0.5 * total
    running = 0.0
    for i in range(kept):
        running += weights[order[i]]
        if running >= half:
            return steps[order[i]], total / kept
    return steps[order[kept - 1]], total / kept
