"""Partition build per GT map against a plain numpy build of the same partition, in one run.

Prints timings and ratios only (nothing is asserted about time) and checks that both builds
give the same cells. Run:

    python bench/bench_partition.py [--repeat N]

The partition is the default one (all + visibility + depth: z-buffer occlusion, boundaries
from GT jumps, 3-means depth classes), built by ``Evaluator.reference`` (which also gathers the
GT in partition order for scoring). The numpy build does the same steps with whole-array
operations: a boolean mask per step, ``np.maximum.at`` for the z-buffer, Lloyd's 3-means on
every valid value, a stable argsort for the order. The process is pinned to one core.
"""

from __future__ import annotations

import argparse
import os

import cv2
import numpy as np
from bench_scoring import CRITERIA, kitti_frame, synthetic_frame, timed

from dispeval_ros import Camera, Evaluator

BINS = 512


def numpy_zbuffer(gt: np.ndarray, valid: np.ndarray, tolerance: float = 1.0) -> np.ndarray:
    """Occluded points: landing outside the image or behind a nearer point (z-buffer)."""
    height, width = gt.shape
    ys, xs = np.nonzero(valid)
    d = gt[ys, xs].astype(np.float64)
    target = np.floor(xs - d + 0.5).astype(np.int64)
    inside = (target >= 0) & (target < width)
    flat = ys[inside] * width + target[inside]
    zbuffer = np.full(height * width, -np.inf)
    np.maximum.at(zbuffer, flat, d[inside])
    hidden = np.zeros(xs.size, bool)
    hidden[inside] = zbuffer[flat] > d[inside] + tolerance
    occluded = np.zeros(gt.shape, bool)
    occluded[ys, xs] = ~inside | hidden
    return occluded


def numpy_boundary(
    gt: np.ndarray, valid: np.ndarray, gap: float = 2.0, size: int = 9
) -> np.ndarray:
    """Points within a size × size square of a jump larger than ``gap`` between valid points."""
    d = np.where(valid, gt, 0.0).astype(np.float32)
    jump = np.zeros(gt.shape, np.uint8)
    across = valid[:, 1:] & valid[:, :-1] & (np.abs(d[:, 1:] - d[:, :-1]) > gap)
    down = valid[1:] & valid[:-1] & (np.abs(d[1:] - d[:-1]) > gap)
    jump[:, 1:] |= across
    jump[:, :-1] |= across
    jump[1:] |= down
    jump[:-1] |= down
    return cv2.dilate(jump, np.ones((size, size), np.uint8)).astype(bool)


def numpy_thresholds(values: np.ndarray) -> tuple[float, float]:
    """3-means of 1-D values: optimal split of a 512-bin histogram, then Lloyd on the values."""
    lo, hi = float(values.min()), float(values.max())
    scale = BINS / (hi - lo) if hi > lo else 0.0
    bins = np.minimum(((values - lo) * scale).astype(np.int64), BINS - 1)
    weight = np.bincount(bins, minlength=BINS).astype(np.float64)
    total = np.bincount(bins, weights=values, minlength=BINS)
    square = np.bincount(bins, weights=values * values, minlength=BINS)
    keep = weight > 0
    prefix = [np.concatenate([[0.0], np.cumsum(a[keep])]) for a in (weight, total, square)]
    n = int(keep.sum())
    cut = np.arange(n + 1)
    first, second = cut[:, None], cut[None, :]

    def error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        w = prefix[0][b] - prefix[0][a]
        s = prefix[1][b] - prefix[1][a]
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(w > 0, prefix[2][b] - prefix[2][a] - s * s / w, 0.0)

    cost = error(np.zeros_like(first), first) + error(first, second) + error(second, n + 0 * first)
    cost[(first < 1) | (first > n - 2) | (second <= first) | (second > n - 1)] = np.inf
    i, j = np.unravel_index(int(np.argmin(cost)), cost.shape)
    w, s = prefix[0], prefix[1]
    centroids = np.array(
        [s[i] / w[i], (s[j] - s[i]) / (w[j] - w[i]), (s[n] - s[j]) / (w[n] - w[j])]
    )
    for _ in range(100):
        low, high = (centroids[:2] + centroids[1:]) / 2
        groups = [values <= low, (values > low) & (values <= high), values > high]
        updated = np.array([values[g].mean() for g in groups])
        if np.array_equal(updated, centroids):
            break
        centroids = updated
    low, high = (centroids[:2] + centroids[1:]) / 2
    return float(low), float(high)


def numpy_partition(gt: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Cells, order, offsets and the GT in partition order, the whole-array numpy way."""
    valid = np.isfinite(gt) & (gt > 0)
    visibility = np.where(numpy_zbuffer(gt, valid), 0, np.where(numpy_boundary(gt, valid), 1, 2))
    low, high = numpy_thresholds(gt[valid].astype(np.float64))
    depth = np.where(gt > high, 0, np.where(gt > low, 1, 2))
    cells = np.where(valid, visibility + 3 * depth, -1).astype(np.int32)
    flat = cells.ravel()
    order = np.flatnonzero(flat >= 0)
    order = order[np.argsort(flat[order], kind="stable")]
    offsets = np.concatenate([[0], np.cumsum(np.bincount(flat[order], minlength=9))])
    return cells, order, offsets, gt.ravel()[order]


def bench_case(gt: np.ndarray, camera: Camera, label: str, repeat: int) -> None:
    """Time both builds and check they agree."""
    evaluator = Evaluator(CRITERIA)
    ours = evaluator.reference(gt, camera)
    cells, order, offsets, gt_sorted = numpy_partition(gt)
    same = (
        np.array_equal(ours.partition.cells, cells)
        and np.array_equal(ours.partition.order, order)
        and np.array_equal(ours.partition.offsets, offsets)
        and np.array_equal(ours.gt_sorted, gt_sorted)
    )
    t_ours = timed(lambda: evaluator.reference(gt, camera), repeat)
    t_numpy = timed(lambda: numpy_partition(gt), max(3, repeat // 4))
    height, width = gt.shape
    print(f"\n{width}×{height}  {label}: {int((cells >= 0).sum())} valid GT points")
    print(f"  numpy build                {t_numpy:8.2f} ms   1.0×")
    print(f"  Evaluator.reference        {t_ours:8.2f} ms   {t_numpy / t_ours:5.1f}× faster")
    print(f"  same cells, order, offsets and sorted GT: {same}")


def main() -> None:
    """Run every case."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=20, help="timed builds per measurement")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    print("dispeval_ros partition benchmark (one core; median of", args.repeat, "builds)")
    cases = [synthetic_frame(1242, 375), synthetic_frame(1920, 1080)]
    kitti = kitti_frame()
    if kitti is not None:
        cases.append(kitti)
    for gt, _est, camera, label in cases:
        bench_case(gt, camera, label, args.repeat)


if __name__ == "__main__":
    main()
