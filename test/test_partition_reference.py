"""The compiled partition build against the implementation it replaced, kept here as reference.

The reference is the straightforward numpy build: 3-means by Lloyd on every exact value from
the optimal split of a 512-bin histogram, visibility labels by masked assignment, cells as
the sum of labels times strides and the order by a stable argsort. The compiled build must
give the same partition (cells, order, offsets) and the same thresholds up to rounding in
the sums, on random maps and on every real scene.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from dispeval_ros import Evaluator
from dispeval_ros.core import criteria
from dispeval_ros.errors import DispevalError
from dispeval_ros.io import load_scene

BINS = 512


def reference_thresholds(gt: np.ndarray, valid: np.ndarray) -> tuple[float, float]:
    """Optimal 3-split of a 512-bin histogram, then Lloyd on every exact value (numpy)."""
    values = gt[valid].astype(np.float64)
    lo, hi = float(values.min()), float(values.max())
    scale = BINS / (hi - lo) if hi > lo else 0.0
    bins = np.minimum(((values - lo) * scale).astype(np.int64), BINS - 1)
    counts = np.bincount(bins, minlength=BINS).astype(np.float64)
    sums = np.bincount(bins, weights=values, minlength=BINS)
    squares = np.bincount(bins, weights=values * values, minlength=BINS)
    occupied = counts > 0
    counts, sums, squares = counts[occupied], sums[occupied], squares[occupied]
    n = counts.size
    if n >= 3:
        cw, cs, cq = (np.concatenate([[0.0], np.cumsum(a)]) for a in (counts, sums, squares))

        def sse(start: np.ndarray, stop: np.ndarray) -> np.ndarray:
            weight = cw[stop] - cw[start]
            total = cs[stop] - cs[start]
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.where(weight > 0, cq[stop] - cq[start] - total * total / weight, 0.0)

        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        cost = sse(np.zeros_like(i), i) + sse(i, j) + sse(j, np.full_like(j, n))
        cost[(i < 1) | (i > n - 2) | (j <= i) | (j > n - 1)] = np.inf
        i, j = np.unravel_index(int(np.argmin(cost)), cost.shape)
        centroids = np.array(
            [
                sums[:i].sum() / counts[:i].sum(),
                sums[i:j].sum() / counts[i:j].sum(),
                sums[j:].sum() / counts[j:].sum(),
            ]
        )
    else:
        centroids = np.array([lo + (hi - lo) / 6, lo + (hi - lo) / 2, lo + 5 * (hi - lo) / 6])
    for _ in range(100):
        low, high = (centroids[0] + centroids[1]) / 2, (centroids[1] + centroids[2]) / 2
        members = [values <= low, (values > low) & (values <= high), values > high]
        updated = np.array(
            [values[m].mean() if m.any() else c for m, c in zip(members, centroids, strict=True)]
        )
        if np.array_equal(updated, centroids):
            break
        centroids = updated
    return (centroids[0] + centroids[1]) / 2, (centroids[1] + centroids[2]) / 2


def reference_cells(gt: np.ndarray, masks: dict[str, np.ndarray] | None = None) -> np.ndarray:
    """Cells of all + visibility + depth the numpy way (occlusion and jumps from the library)."""
    masks = masks or {}
    valid = criteria.valid_ground_truth(gt, masks.get("all"))
    occluded, _ = criteria.occlusion(gt, valid, nonocc=masks.get("nonocc"))
    near_jump = masks["disc"] if "disc" in masks else criteria.discontinuities(gt, valid)
    visibility = np.full(gt.shape, 2, np.int32)
    visibility[near_jump] = 1
    visibility[occluded] = 0
    low, high = reference_thresholds(gt, valid)
    depth = np.where(gt > high, 0, np.where(gt > low, 1, 2))
    cells = visibility + 3 * depth
    cells[~valid] = -1
    return cells


def assert_same_partition(gt: np.ndarray, masks: dict[str, np.ndarray] | None = None) -> None:
    """The compiled build gives the reference's cells, order, offsets and thresholds."""
    masks = masks or {}
    partition = Evaluator(("all", "visibility", "depth")).reference(gt, masks=masks).partition
    cells = reference_cells(gt, masks)
    np.testing.assert_array_equal(partition.cells, cells)
    flat = cells.ravel()
    kept = np.flatnonzero(flat >= 0)
    order = kept[np.argsort(flat[kept], kind="stable")]
    np.testing.assert_array_equal(partition.order, order)
    offsets = np.concatenate([[0], np.cumsum(np.bincount(flat[kept], minlength=9))])
    np.testing.assert_array_equal(partition.offsets, offsets)
    valid = criteria.valid_ground_truth(gt, masks.get("all"))
    ours = criteria.kmeans_thresholds(gt, valid)
    np.testing.assert_allclose(ours, reference_thresholds(gt, valid), rtol=1e-12)


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
    invalid = draw(hnp.arrays(np.uint8, (height, width), elements=st.integers(0, 9)))
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
