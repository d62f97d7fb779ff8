"""The compiled partition build against the implementation it replaced, kept here as reference.

The reference is the straightforward numpy build (also the baseline of
``bench/bench_partition.py``): a z-buffer by ``np.maximum.at``, boundaries from array
differences, 3-means by Lloyd on every exact value from the optimal split of a 512-bin
histogram, cells from nested ``np.where`` and the order by a stable argsort. The compiled
build must give the same partition (cells, order, offsets, GT in partition order) and the
same thresholds up to rounding in the sums, on random maps and on every real scene.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from dispeval_ros import Camera, Evaluator
from dispeval_ros.core import criteria, kernels
from dispeval_ros.core.criteria import is_sparse
from dispeval_ros.errors import DispevalError
from dispeval_ros.io import load_scene

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


def numpy_sparse_boundary(
    gt: np.ndarray, valid: np.ndarray, gap: float = 2.0, size: int = 9
) -> np.ndarray:
    """Sparse GT: valid points with a valid point in their size × size square off by > ``gap``.

    Such a point exists iff the square's largest valid value exceeds d + gap or its smallest
    falls below d − gap: a max and a min filter over the valid values.
    """
    kernel = np.ones((size, size), np.uint8)
    d = gt.astype(np.float32)
    highest = cv2.dilate(np.where(valid, d, -np.inf).astype(np.float32), kernel)
    lowest = cv2.erode(np.where(valid, d, np.inf).astype(np.float32), kernel)
    return valid & ((highest - d > gap) | (d - lowest > gap))


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

    if n >= 3:  # the best pair of cuts; else centroids spread over the range
        cost = error(np.zeros_like(first), first) + error(first, second)
        cost += error(second, n + 0 * first)
        cost[(first < 1) | (first > n - 2) | (second <= first) | (second > n - 1)] = np.inf
        i, j = np.unravel_index(int(np.argmin(cost)), cost.shape)
        w, s = prefix[0], prefix[1]
        centroids = np.array(
            [s[i] / w[i], (s[j] - s[i]) / (w[j] - w[i]), (s[n] - s[j]) / (w[n] - w[j])]
        )
    else:
        centroids = lo + (hi - lo) * np.array([1 / 6, 1 / 2, 5 / 6])
    for _ in range(100):
        low, high = (centroids[:2] + centroids[1:]) / 2
        groups = [values <= low, (values > low) & (values <= high), values > high]
        updated = np.array(
            [values[g].mean() if g.any() else c for g, c in zip(groups, centroids, strict=True)]
        )
        if np.array_equal(updated, centroids):
            break
        centroids = updated
    low, high = (centroids[:2] + centroids[1:]) / 2
    return float(low), float(high)


def numpy_partition(
    gt: np.ndarray, masks: Mapping[str, np.ndarray] | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Cells, order, offsets and the GT in partition order, the whole-array numpy way.

    ``masks``: official ``all`` / ``nonocc`` / ``disc`` masks, used where given.
    """
    masks = masks or {}
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(gt) & (gt > 0)
    if "all" in masks:
        valid &= masks["all"]
    occluded = valid & ~masks["nonocc"] if "nonocc" in masks else numpy_zbuffer(gt, valid)
    if "disc" in masks:
        near_jump = masks["disc"]
    elif is_sparse(valid):  # LiDAR-like GT: the window rule (METHOD-level change of issue 10)
        near_jump = numpy_sparse_boundary(gt, valid)
    else:
        near_jump = numpy_boundary(gt, valid)
    visibility = np.where(occluded, 0, np.where(near_jump, 1, 2))
    low, high = numpy_thresholds(gt[valid].astype(np.float64))
    with np.errstate(invalid="ignore"):
        depth = np.where(gt > high, 0, np.where(gt > low, 1, 2))
    cells = np.where(valid, visibility + 3 * depth, -1).astype(np.int32)
    flat = cells.ravel()
    order = np.flatnonzero(flat >= 0)
    order = order[np.argsort(flat[order], kind="stable")]
    offsets = np.concatenate([[0], np.cumsum(np.bincount(flat[order], minlength=9))])
    return cells, order, offsets, gt.ravel()[order]


def assert_same_partition(gt: np.ndarray, masks: dict[str, np.ndarray] | None = None) -> None:
    """The compiled build gives the reference's cells, order, offsets, GT order and thresholds."""
    masks = masks or {}
    reference = Evaluator(("all", "visibility", "depth")).reference(gt, masks=masks)
    cells, order, offsets, gt_sorted = numpy_partition(gt, masks)
    np.testing.assert_array_equal(reference.partition.cells, cells)
    np.testing.assert_array_equal(reference.partition.order, order)
    np.testing.assert_array_equal(reference.partition.offsets, offsets)
    np.testing.assert_array_equal(reference.gt_sorted, gt_sorted)
    valid = criteria.valid_ground_truth(gt, masks.get("all"))
    ours = criteria.kmeans_thresholds(gt, valid)
    np.testing.assert_allclose(ours, numpy_thresholds(gt[valid].astype(np.float64)), rtol=1e-12)


@st.composite
def disparity_maps(draw: st.DrawFn) -> np.ndarray:
    """Small maps: smooth, quantised (many equal values) or heavy-tailed, with invalid points."""
    height, width = draw(st.integers(1, 24)), draw(st.integers(1, 32))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    kind = draw(st.sampled_from(["uniform", "quantised", "gamma", "rows"]))
    if kind == "uniform":
        gt = rng.uniform(0.1, 60.0, (height, width))
    elif kind == "quantised":
        gt = np.round(rng.uniform(0.0, 20.0, (height, width)) * 4) / 4
    elif kind == "gamma":
        gt = rng.gamma(2.0, 8.0, (height, width))
    else:
        gt = np.repeat(rng.uniform(1, 30, (height, 1)), width, axis=1)
        gt = gt + rng.integers(0, 3, (height, width))
    top = draw(st.sampled_from([9, 3]))  # about 30 % or 75 % of the points invalid
    invalid = draw(hnp.arrays(np.uint8, (height, width), elements=st.integers(0, top)))
    gt[invalid == 0] = 0.0
    gt[invalid == 1] = np.nan
    gt[invalid == 2] = np.inf
    gt = gt.astype(np.float32)
    gt.flat[seed % gt.size] = 5.0  # at least one valid point
    return gt


@settings(max_examples=150, deadline=None)
@given(disparity_maps())
def test_partition_matches_reference_on_random_maps(gt: np.ndarray) -> None:
    assert_same_partition(gt)


def test_partition_matches_reference_on_dense_frames() -> None:
    rng = np.random.default_rng(8)
    ramp = np.linspace(5.0, 80.0, 1242, dtype=np.float32)[None, :] * np.ones((375, 1), np.float32)
    assert_same_partition(ramp + rng.normal(0, 0.3, ramp.shape).astype(np.float32))
    quantised = np.round(ramp * 4) / 4  # many points exactly on the same values
    assert_same_partition(quantised.astype(np.float32))


def test_partition_matches_reference_in_every_regime_of_the_kernels() -> None:
    """Long and short runs of one cell; 3-means on every value or on the packed valid ones."""
    rng = np.random.default_rng(11)
    ramp = np.linspace(5.0, 80.0, 640, dtype=np.float32)[None, :] * np.ones((120, 1), np.float32)
    sparse = ramp.copy()
    sparse[rng.random(ramp.shape) < 0.8] = np.nan  # 20 % valid, scattered: short runs
    for gt, packed, long_runs in ((ramp, False, True), (sparse, True, False)):
        valid = criteria.valid_ground_truth(gt)
        assert (valid.mean() < criteria.SPARSE_KMEANS_SHARE) == packed
        cells = Evaluator(("all", "visibility", "depth")).reference(gt).partition.cells.ravel()
        changes = int(np.count_nonzero(cells[1:] != cells[:-1]))
        assert (changes * kernels.RUN_PIXELS < cells.size) == long_runs
        assert_same_partition(gt)


def _scene_folders(root: Path) -> list[Path]:
    return sorted(p for p in root.glob("*/*") if p.is_dir()) + [
        p for p in root.glob("*") if p.is_dir()
    ]


def test_partition_matches_reference_on_real_scenes(shared_data: Path) -> None:
    scenes = 0
    for folder in _scene_folders(shared_data):
        try:
            loaded = load_scene(folder)
        except DispevalError:  # folders that are not one scene (devkits, bags)
            continue
        assert_same_partition(loaded.gt)
        if loaded.masks:
            assert_same_partition(loaded.gt, dict(loaded.masks))
        scenes += 1
    assert scenes >= 20


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (5, 1)])
def test_partition_matches_reference_on_tiny_maps(shape: tuple[int, int]) -> None:
    assert_same_partition(np.arange(1, shape[0] * shape[1] + 1, dtype=np.float32).reshape(shape))


def test_partition_matches_reference_when_lloyd_crosses_many_bins() -> None:
    # One far outlier puts the bulk in the first bins: the thresholds start far from their
    # fixpoint and cross hundreds of bins (the kernel copies the bins it splits again).
    rng = np.random.default_rng(3)
    for extra in ([], [3.0] * 50, list(rng.uniform(200, 300, 80))):
        values = np.concatenate([rng.uniform(1, 2, 600), extra, [1e6, 2e5]]).astype(np.float32)
        gt = np.zeros(32 * 32, np.float32)
        gt[: values.size] = values
        assert_same_partition(gt.reshape(32, 32))


@pytest.mark.parametrize(
    "names",
    [
        ("all",),
        ("depth",),
        ("visibility", "depth"),
        ("depth", "all", "visibility"),
        ("visibility", "legacy"),
        ("legacy", "depth", "visibility"),
    ],
)
def test_standard_partition_is_build_partition_of_the_sets(names: tuple[str, ...]) -> None:
    rng = np.random.default_rng(5)
    gt = (np.linspace(5.0, 60.0, 80)[None, :] + rng.normal(0, 0.5, (50, 80))).astype(np.float32)
    gt[rng.random(gt.shape) < 0.1] = np.nan
    nonocc = rng.random(gt.shape) < 0.9
    for masks in ({}, {"nonocc": nonocc}):
        valid = criteria.valid_ground_truth(gt)
        visibility = criteria.visibility_set(gt, valid, nonocc=masks.get("nonocc"))
        made = {
            "all": criteria.all_set(valid),
            "visibility": visibility,
            "legacy": criteria.legacy_set(visibility),
            "depth": criteria.depth_set(gt, valid),
        }
        expected = criteria.build_partition(valid, [made[name] for name in names])
        options = criteria.VisibilityOptions(nonocc=masks.get("nonocc"))
        ours, gt_sorted = criteria.standard_partition(gt, valid, names, options)
        assert_same_layout(ours, expected)
        np.testing.assert_array_equal(gt_sorted, gt.ravel()[expected.order])
        # metric depth ranges: the depth classes come as a label image
        camera = Camera(f=700.0, baseline=0.5)
        made["depth"] = criteria.depth_set(gt, valid, camera=camera, ranges=RANGES)
        expected = criteria.build_partition(valid, [made[name] for name in names])
        ours, _ = criteria.standard_partition(
            gt, valid, names, options, camera=camera, depth_ranges=RANGES
        )
        assert_same_layout(ours, expected)


RANGES = ((0.0, 8.0), (8.0, 20.0), (20.0, float("inf")))


def assert_same_layout(ours: criteria.Partition, expected: criteria.Partition) -> None:
    """Same cells, order, offsets, criteria, membership, overlapping criteria and sources."""
    for field in ("cells", "order", "offsets", "membership"):
        np.testing.assert_array_equal(getattr(ours, field), getattr(expected, field))
    assert (ours.criteria, ours.overlapping, dict(ours.sources)) == (
        expected.criteria,
        expected.overlapping,
        dict(expected.sources),
    )


@settings(max_examples=60, deadline=None)
@given(disparity_maps(), st.sampled_from([0.0, 0.5, 1.0, 3.0, -1.0, math.nan]))
def test_zbuffer_occlusion_matches_reference_for_any_tolerance(
    gt: np.ndarray, tolerance: float
) -> None:
    valid = criteria.valid_ground_truth(gt)
    occluded, _ = criteria.occlusion(gt, valid, tolerance=tolerance)
    np.testing.assert_array_equal(occluded, numpy_zbuffer(gt, valid, tolerance))
