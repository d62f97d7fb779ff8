"""The ``depth`` set: near / mid / far by a deterministic 3-means or by metric ranges."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dispeval_ros.core import kernels
from dispeval_ros.core.camera import Camera
from dispeval_ros.core.criteria.base import (
    DEPTH,
    CriterionSet,
    _flat,
    _partitioning,
)
from dispeval_ros.errors import ConfigurationError, EmptyGroundTruthError

#: Depth ranges (metres) of the ``depth`` criteria for LiDAR GT: 3-means of a scan's
#: disparities would split mostly by distance along the ground, ranges say what users mean.
LIDAR_DEPTH_RANGES = ((0.0, 10.0), (10.0, 30.0), (30.0, float("inf")))


def kmeans_thresholds(
    gt: np.ndarray, valid: np.ndarray, max_iterations: int = 100
) -> tuple[float, float]:
    """Deterministic 1-D 3-means of the valid GT disparities: the two decision thresholds.

    Lloyd's algorithm can stop in a poor local optimum (on Middlebury tsukuba, twice the
    optimal within-cluster error from range-based starting points), so it starts from the
    global optimum over a fine histogram (every pair of cuts at bin edges, exact bin
    moments) and then iterates on the exact values until the centroids no longer change.
    Each step sums whole bins from their moments and splits value by value only the bins a
    threshold falls in. A value equal to a threshold goes to the lower (farther) cluster.
    ``valid`` marks finite values > 0 only (:func:`valid_ground_truth`, maybe narrowed).
    """
    flat_valid = _flat(valid, np.bool_)
    count = int(np.count_nonzero(flat_valid))
    if not count:
        raise EmptyGroundTruthError("the ground truth has no valid point (all NaN, inf or ≤ 0)")
    values = _flat(gt)
    if values.dtype not in (np.float32, np.float64):
        values = values.astype(np.float64)
    if count < SPARSE_KMEANS_SHARE * flat_valid.shape[0]:  # mostly invalid: read only the valid
        packed = np.empty(count + 1, dtype=values.dtype)  # + 1: the kernel writes one past
        kernels.pack_valid(values, flat_valid, packed)
        values, flat_valid = packed[:count], np.ones(count, dtype=np.bool_)
    bits = values.view(np.int32 if values.dtype == np.float32 else np.int64)
    limits = np.array([np.iinfo(bits.dtype).max, -1], dtype=bits.dtype)
    kernels.valid_range(bits, flat_valid, limits)
    lo, hi = (float(value) for value in limits.view(values.dtype))
    thresholds = np.empty(2)
    kernels.kmeans_three(
        values,
        flat_valid,
        lo,
        hi,
        max_iterations,
        np.zeros(_KMEANS_BINS + 1, dtype=np.int64),
        np.zeros((8, _KMEANS_BINS + 1)),
        np.empty(values.shape[0]),  # untouched pages cost nothing: only a few bins are copied
        np.empty(values.shape[0], dtype=np.uint16),
        thresholds,
    )
    return float(thresholds[0]), float(thresholds[1])


_KMEANS_BINS = 512
#: Below this share of valid points, 3-means packs the valid values first (sparse GT).
SPARSE_KMEANS_SHARE = 0.5


def depth_set(
    gt: np.ndarray,
    valid: np.ndarray,
    *,
    camera: Camera | None = None,
    ranges: Sequence[tuple[float, float]] | None = None,
    names: Sequence[str] | None = None,
) -> CriterionSet:
    """``near`` / ``mid`` / ``far`` by 3-means of the disparities, or by metric depth ranges.

    Ranges are ``(from, to)`` in the camera's unit, contiguous, from 0 to ``inf``; points
    with ``d + doffs <= 0`` (infinitely far) fall in the last range.
    """
    if ranges is None:
        low, high = kmeans_thresholds(gt, valid)
        labels = np.empty(gt.shape, np.int32)
        kernels.threshold_labels(_flat(gt), low, high, labels.reshape(-1))
        return _partitioning("depth", labels, DEPTH, _thresholds_text(low, high))
    if camera is None:
        raise ConfigurationError("metric depth ranges need a camera (focal length and baseline)")
    edges = _range_edges(ranges)
    criteria = tuple(names) if names else tuple(_range_name(a, b, camera.unit) for a, b in ranges)
    if len(criteria) != len(ranges):
        raise ConfigurationError(f"{len(ranges)} depth ranges but {len(criteria)} names")
    denominator = np.where(valid, gt, 0.0).astype(np.float64) + camera.doffs
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.where(denominator > 0, camera.fb / denominator, np.inf)
    labels = np.searchsorted(edges, depth, side="right").astype(np.int32) - 1
    labels = np.clip(labels, 0, len(criteria) - 1)
    return _partitioning("depth", labels, criteria, "metric depth ranges")


def _thresholds_text(low: float, high: float) -> str:
    return f"3-means thresholds {low:.6g}, {high:.6g} px"


def _range_edges(ranges: Sequence[tuple[float, float]]) -> np.ndarray:
    if not ranges:
        raise ConfigurationError("depth ranges are empty; give e.g. 0-10,10-30,30-inf")
    starts = [float(a) for a, _ in ranges]
    stops = [float(b) for _, b in ranges]
    if (
        starts[0] != 0.0
        or stops[-1] != np.inf
        or any(a != b for a, b in zip(stops[:-1], starts[1:], strict=True))
        or any(a >= b for a, b in zip(starts, stops, strict=True))
    ):
        shown = ", ".join(f"{a:g}-{b:g}" for a, b in ranges)
        raise ConfigurationError(
            f"depth ranges must be contiguous and increasing from 0 to inf, got {shown}"
        )
    return np.array(starts, dtype=np.float64)


def _range_name(start: float, stop: float, unit: str) -> str:
    return f"{start:g}+{unit}" if stop == np.inf else f"{start:g}-{stop:g}{unit}"
