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
    depth, the landing and the bilinear value all move with ``b``). In blocks of
    :data:`BLOCK` samples: their inputs gathered, the geometry in one vectorised pass
    (:func:`_fit_geometry`, 0.33 → 0.23 ms per pass on the bench), then the target's reads.
    """
    height, width = source.shape
    photo = images[0].shape[0] == height and images[1].shape[0] == height
    us = _columns(width, geo)  # (x − cx)/f per column and (y − cy)/f per row: once, not per pixel
    vs = np.empty(height, np.float64)
    for y in range(height):
        vs[y] = (y - geo[2]) / geo[0]
    block = np.empty((_GEOMETRY, min(BLOCK, samples.shape[0])), np.float64)
    written = 0
    for first in range(0, samples.shape[0], BLOCK):
        n = min(BLOCK, samples.shape[0] - first)
        for i in range(n):  # the gathers, bare; then one vectorised pass of arithmetic
            y = samples[first + i, 0]
            x = samples[first + i, 1]
            block[_S, i] = source[y, x]
            block[_U, i] = us[x]
            block[_V, i] = vs[y]
        _fit_geometry(block, n, rt, geo, offset, (np.float64(width - 1), np.float64(height - 1)))
        part = samples[first : first + n]
        written = _fit_block(
            part, block, target, images, photo, (offset, photometric), out, written
        )
    return written


BLOCK = 512
"""Samples per block of the fit's geometry: its rows stay in the first-level cache."""
_S, _U, _V, _XP, _YP, _PREDICTED, _DXP, _DYP, _DZ = range(9)
_GEOMETRY = 9
"""Rows of a block: ``s``, ``u``, ``v`` in; landing, predicted disparity, slope terms out."""


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _fit_geometry(
    block: np.ndarray,
    n: int,
    rt: np.ndarray,
    geo: np.ndarray,
    offset: float,
    last: tuple[float, float],
) -> None:  # pragma: no cover - compiled
    """Landing and slope terms of ``n`` samples, branch-free (it vectorises).

    A sample that does not land (no depth, behind the camera, outside the image) gets a NaN
    landing, which :func:`_fit_block` skips. Per sample the operations are those of the
    definition in the same order (the same values, bit for bit).
    """
    f, cx, cy, fb, doffs = geo[0], geo[1], geo[2], geo[3], geo[4]
    last_x, last_y = last
    for i in range(n):
        s = block[_S, i] - offset + doffs
        z = fb / s
        u = block[_U, i]
        v = block[_V, i]
        ax = rt[0, 0] * u + rt[0, 1] * v + rt[0, 2]
        ay = rt[1, 0] * u + rt[1, 1] * v + rt[1, 2]
        az = rt[2, 0] * u + rt[2, 1] * v + rt[2, 2]
        qx = z * ax + rt[0, 3]
        qy = z * ay + rt[1, 3]
        qz = z * az + rt[2, 3]
        xp = cx + f * qx / qz
        yp = cy + f * qy / qz
        ok = (s > 0.0) & (qz > 0.0) & (xp >= 0.0) & (xp <= last_x) & (yp >= 0.0) & (yp <= last_y)
        dz = z * z / fb
        block[_XP, i] = xp if ok else np.nan
        block[_YP, i] = yp
        block[_PREDICTED, i] = fb / qz - doffs
        block[_DXP, i] = f * (ax * qz - qx * az) / (qz * qz) * dz
        block[_DYP, i] = f * (ay * qz - qy * az) / (qz * qz) * dz
        block[_DZ, i] = fb * az * dz / (qz * qz)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _fit_block(
    samples: np.ndarray,
    block: np.ndarray,
    target: tuple[np.ndarray, np.ndarray],
    images: tuple[np.ndarray, np.ndarray],
    photo: bool,
    levels: tuple[float, float],
    out: tuple[np.ndarray, np.ndarray],
    written: int,
) -> int:  # pragma: no cover - compiled
    """The block's samples that land, read the target and pass the checks, appended to ``out``.

    ``levels``: (offset, photometric threshold). Returns the new count written.
    """
    tgt, tgt_edges = target
    src_image, tgt_image = images
    offset, photometric = levels
    height, width = tgt.shape
    residuals, slopes = out
    for i in range(samples.shape[0]):
        xp = block[_XP, i]
        if not xp >= 0.0:  # NaN: the sample does not land
            continue
        yp = block[_YP, i]
        x0 = min(int(xp), width - 2)
        y0 = min(int(yp), height - 2)
        wx = xp - x0
        wy = yp - y0
        p00 = np.float64(tgt[y0, x0])  # the support, loaded once for the value and slopes
        p01 = np.float64(tgt[y0, x0 + 1])
        p10 = np.float64(tgt[y0 + 1, x0])
        p11 = np.float64(tgt[y0 + 1, x0 + 1])
        r = _blend(p00, p01, p10, p11, wx, wy) - offset - block[_PREDICTED, i]
        if not abs(r) < np.inf or tgt_edges[int(yp + 0.5), int(xp + 0.5)]:
            continue
        y = samples[i, 0]
        x = samples[i, 1]
        if photo and (
            abs(np.float64(src_image[y, x]) - _bilinear(tgt_image, x0, y0, wx, wy)) > photometric
        ):
            continue
        gx = (1.0 - wy) * (p01 - p00) + wy * (p11 - p10)
        gy = (1.0 - wx) * (p10 - p00) + wx * (p11 - p01)
        residuals[written] = r
        slopes[written] = gx * block[_DXP, i] + gy * block[_DYP, i] + block[_DZ, i] - 1.0
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
