"""Sparse ground truth from a LiDAR: project a point cloud into the left rectified camera.

``X_rect = R · T · X_lidar`` (``T``: the LiDAR → camera extrinsic, ``R``: the left camera's
rectification), ``[u·w, v·w, w] = P · X_rect``. A point lands on pixel ``(⌊u + ½⌋, ⌊v + ½⌋)``
(round half up) when ``w > 0`` and that pixel is inside the image; where several points land on
one pixel the nearest (smallest ``w``) wins. Its ground-truth disparity is ``f·B / w − doffs``
(the camera's depth convention ``Z = f·B / (d + doffs)``; ``doffs = 0`` for ROS-rectified
pairs).

The LiDAR does not sit where the camera does, so it sees background through the edges of
foreground objects that hide that background from the camera; those points project onto the
foreground's pixels with the background's depth. :class:`CloudFilter` removes them: a point is
dropped when a point within a ``w × w`` pixel window around it is nearer by more than the
relative gap ``g`` (``Z_near · (1 + g) < Z``). The filter works on the z-buffered image.

Everything here is pure (arrays in, arrays out); the loops are numba-compiled.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np
from numba import njit

from dispeval_ros.core.camera import Camera
from dispeval_ros.errors import CalibrationError, ConfigurationError, InputError

#: Default parallax filter: a 7×7 window and a relative gap of 10 %.
DEFAULT_FILTER_WINDOW = 7
DEFAULT_FILTER_GAP = 0.1


@dataclass(frozen=True)
class CloudFilter:
    """The LiDAR–camera parallax filter: window side ``window`` (odd, px; 0 = off), gap ``gap``."""

    window: int = DEFAULT_FILTER_WINDOW
    gap: float = DEFAULT_FILTER_GAP

    def __post_init__(self) -> None:
        even = isinstance(self.window, int) and self.window > 0 and self.window % 2 == 0
        if not isinstance(self.window, int) or self.window < 0 or even:
            raise ConfigurationError(
                "cloud filter window must be an odd number of px (centred on the point), or 0 "
                f"to disable, got {self.window!r}"
            )
        if not (isinstance(self.gap, (int, float)) and math.isfinite(self.gap) and self.gap >= 0):
            raise ConfigurationError(f"cloud filter gap must be a number ≥ 0, got {self.gap!r}")

    @property
    def enabled(self) -> bool:
        """Whether the filter removes anything (``window > 1``; 1 holds only the point itself)."""
        return self.window > 1

    @classmethod
    def parse(cls, text: str) -> CloudFilter:
        """``"W,G"`` (e.g. ``"7,0.1"``) or ``"0"`` (off)."""
        parts = [part.strip() for part in str(text).split(",")]
        try:
            if len(parts) == 1 and float(parts[0]) == 0:
                return cls(0, DEFAULT_FILTER_GAP)
            if len(parts) == 2:
                window = float(parts[0])
                if window.is_integer():
                    return cls(int(window), float(parts[1]))
        except ValueError:
            pass
        raise ConfigurationError(
            f"cloud filter must be 'W,G' (window in px, relative gap, e.g. "
            f"'{DEFAULT_FILTER_WINDOW},{DEFAULT_FILTER_GAP:g}') or '0' to disable, got {text!r}"
        )

    def __str__(self) -> str:
        return f"{self.window},{self.gap:g}" if self.enabled else "0"


@dataclass(frozen=True)
class CloudProjection:
    """A projected cloud: the sparse GT disparity map and what happened to the points.

    ``disparity`` is float32, 0 where no point landed. ``points`` is the number of finite
    input points, ``in_front`` those with ``Z > 0``, ``inside`` those also inside the image,
    ``kept`` the pixels with a value after the z-buffer and ``removed`` the pixels the
    parallax filter emptied (``kept`` counts after the filter).
    """

    disparity: np.ndarray
    points: int
    in_front: int
    inside: int
    kept: int
    removed: int


def rectified_projection(
    extrinsic: np.ndarray, rectification: np.ndarray, projection: np.ndarray
) -> np.ndarray:
    """The 3×4 matrix ``P · R · T`` that maps LiDAR points to homogeneous pixels."""
    transform = _matrix(extrinsic, (4, 4), "the LiDAR extrinsic")
    rect = np.eye(4)
    rect[:3, :3] = _matrix(rectification, (3, 3), "the rectification R")
    p = _matrix(projection, (3, 4), "the projection P")
    return p @ rect @ transform


def _matrix(values: np.ndarray, shape: tuple[int, int], what: str) -> np.ndarray:
    array = np.asarray(values, dtype=np.float64)
    if array.size != shape[0] * shape[1]:
        raise CalibrationError(f"{what} must have {shape[0]}×{shape[1]} values, got {array.size}")
    array = array.reshape(shape)
    if not np.isfinite(array).all():
        raise CalibrationError(f"{what} holds non-finite values")
    return array


def project_cloud(
    points: np.ndarray,
    matrix: np.ndarray,
    shape: tuple[int, int],
    camera: Camera,
    cloud_filter: CloudFilter | None = None,
) -> CloudProjection:
    """Project LiDAR ``points`` (N×3) through ``matrix`` (:func:`rectified_projection`).

    ``shape`` is the image's (rows, columns); ``camera`` gives ``f·B`` and ``doffs``. Non-finite
    points are skipped. ``cloud_filter`` defaults to :class:`CloudFilter` () (``window=0``: off).
    """
    xyz = np.asarray(points)
    if xyz.ndim != 2 or xyz.shape[1] != 3:
        raise InputError(f"a point cloud must be an N×3 array of x, y, z, got shape {xyz.shape}")
    if xyz.dtype not in (np.float32, np.float64):
        xyz = xyz.astype(np.float64)
    height, width = int(shape[0]), int(shape[1])
    if height <= 0 or width <= 0:
        raise ConfigurationError(f"image size must be positive, got {width}×{height}")
    chosen = CloudFilter() if cloud_filter is None else cloud_filter
    m = _matrix(matrix, (3, 4), "the projection matrix")
    depth = _depth_buffer(height, width)
    rows_min = _rows_buffer(height, width)
    disparity = np.zeros((height, width), dtype=np.float32)
    counts = _project(
        np.ascontiguousarray(xyz),
        m,
        depth,
        rows_min,
        float(camera.fb),
        float(camera.doffs),
        chosen.window if chosen.enabled else 0,
        float(chosen.gap),
        disparity,
    )
    return CloudProjection(disparity, *(int(c) for c in counts))


_BUFFERS = threading.local()


def _rows_buffer(height: int, width: int) -> np.ndarray:
    """This thread's row-minimum buffer for the filter (float32, all ``inf``, as the z-buffer)."""
    buffer = getattr(_BUFFERS, "rows", None)
    if buffer is None or buffer.shape != (height, width):
        buffer = np.full((height, width), np.inf, dtype=np.float32)
        _BUFFERS.rows = buffer
    return buffer


def _depth_buffer(height: int, width: int) -> np.ndarray:
    """This thread's z-buffer (float32, all ``inf``), kept between calls of one image size.

    The kernel leaves it all ``inf`` again by resetting only the pixels it touched, so a
    frame costs no full-image fill.
    """
    buffer = getattr(_BUFFERS, "depth", None)
    if buffer is None or buffer.shape != (height, width):
        buffer = np.full((height, width), np.inf, dtype=np.float32)
        _BUFFERS.depth = buffer
    return buffer


@njit(cache=True, nogil=True)
def _project(
    xyz: np.ndarray,
    m: np.ndarray,
    depth: np.ndarray,
    rows_min: np.ndarray,
    fb: float,
    doffs: float,
    window: int,
    gap: float,
    disparity: np.ndarray,
) -> tuple[int, int, int, int, int]:  # pragma: no cover - compiled
    """z-buffer projection, parallax filter and disparity in one call (see the module).

    The filter's window minimum is separable: each kept pixel first spreads its depth over its
    row's ``window`` columns (``rows_min``), then each reads ``window`` rows of one column —
    3·W memory operations per point with the reset, instead of W².
    """
    height, width = depth.shape
    flat_depth = depth.ravel()  # all inf on entry; touched pixels are reset on exit
    hit = np.empty(min(xyz.shape[0], height * width), dtype=np.int64)
    n_hit = 0
    finite = 0
    in_front = 0
    inside = 0
    for i in range(xyz.shape[0]):
        x = np.float64(xyz[i, 0])
        y = np.float64(xyz[i, 1])
        z = np.float64(xyz[i, 2])
        if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z)):
            continue
        finite += 1
        w = m[2, 0] * x + m[2, 1] * y + m[2, 2] * z + m[2, 3]
        if not w > 0.0:
            continue
        in_front += 1
        u = (m[0, 0] * x + m[0, 1] * y + m[0, 2] * z + m[0, 3]) / w
        v = (m[1, 0] * x + m[1, 1] * y + m[1, 2] * z + m[1, 3]) / w
        col_f = np.floor(u + 0.5)
        row_f = np.floor(v + 0.5)
        if not (0.0 <= col_f < width and 0.0 <= row_f < height):
            continue
        inside += 1
        index = int(row_f) * width + int(col_f)
        previous = flat_depth[index]
        if previous == np.inf:
            hit[n_hit] = index
            n_hit += 1
        if w < previous:
            flat_depth[index] = np.float32(w)
    removed = 0
    half = window // 2
    flat_disparity = disparity.ravel()
    flat_rows = rows_min.ravel()
    if window > 1:
        for k in range(n_hit):  # each row's minimum over the horizontal window
            index = hit[k]
            z = flat_depth[index]
            row = index // width
            col = index - row * width
            base = row * width
            for c in range(base + max(col - half, 0), base + min(col + half + 1, width)):
                flat_rows[c] = min(flat_rows[c], z)
    for k in range(n_hit):
        index = hit[k]
        z = flat_depth[index]
        keep = True
        if window > 1:
            row = index // width
            col = index - row * width
            limit = np.float32(z / (1.0 + gap))
            nearest = np.float32(np.inf)
            for r in range(max(row - half, 0), min(row + half + 1, height)):
                nearest = min(nearest, flat_rows[r * width + col])
            keep = not nearest < limit
        if keep:
            flat_disparity[index] = fb / np.float64(z) - doffs
        else:
            removed += 1
    for k in range(n_hit):
        index = hit[k]
        flat_depth[index] = np.inf
        if window > 1:
            row = index // width
            col = index - row * width
            base = row * width
            for c in range(base + max(col - half, 0), base + min(col + half + 1, width)):
                flat_rows[c] = np.inf
    return finite, in_front, inside, n_hit - removed, removed
