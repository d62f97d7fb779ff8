"""The evaluator's reference cache: reuse, invalidation, cameras, masks, bit patterns.

Conventions of the code under test: reference.py (METHOD.md §1–3).
"""

from __future__ import annotations

import numpy as np
import pytest

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.evaluator import Evaluator


def test_cache_reuses_and_invalidates_on_in_place_change() -> None:
    rng = np.random.default_rng(3)
    gt = rng.uniform(1, 30, (12, 15)).astype(np.float32)
    est = (gt + rng.normal(0, 1.5, gt.shape)).astype(np.float32)
    evaluator = Evaluator()
    first = evaluator.score(gt, est)
    again = evaluator.score(gt, est)
    np.testing.assert_array_equal(first.sums, again.sums)
    # change the GT in place: the same object now means a different reference
    gt[:4] = 0.0
    gt[5, :] = 60.0
    changed = evaluator.score(gt, est)
    fresh = Evaluator().score(gt, est)
    np.testing.assert_array_equal(changed.sums, fresh.sums)
    assert changed["all"]["n"] == 12 * 15 - 4 * 15
    assert not np.array_equal(changed.sums, first.sums)
    # a GT of another dtype (converted on every call) behaves the same way
    gt64 = gt.astype(np.float64)
    before = evaluator.score(gt64, est)
    gt64[6:8] = np.nan
    after = evaluator.score(gt64, est)
    np.testing.assert_array_equal(after.sums, Evaluator().score(gt64, est).sums)
    assert after["all"]["n"] == before["all"]["n"] - 30


def test_cache_distinguishes_cameras() -> None:
    gt = np.full((3, 3), 10.0, np.float32)
    est = np.full((3, 3), 12.0, np.float32)
    evaluator = Evaluator(criteria=("all",))
    near = evaluator.score(gt, est, Camera(f=100.0, baseline=1.0))["all"]["sze"]
    far = evaluator.score(gt, est, Camera(f=200.0, baseline=1.0))["all"]["sze"]
    assert far == pytest.approx(2 * near, rel=1e-9)
    assert evaluator.score(gt, est).relative


def test_cache_follows_masks_and_roi_contents() -> None:
    gt = np.full((4, 6), 3.0, np.float32)
    visibility = Evaluator(criteria=("visibility",), measures=("bmp",))
    masks = {"nonocc": np.ones((4, 6), bool)}
    assert visibility.score(gt, gt, masks=masks)["occluded"]["n"] == 0
    masks["nonocc"] = np.zeros((4, 6), bool)  # same dict, new mask: 24 occluded points
    assert visibility.score(gt, gt, masks=masks)["occluded"]["n"] == 24
    masks["nonocc"][:, :2] = True  # the same array changed in place
    assert visibility.score(gt, gt, masks=masks)["occluded"]["n"] == 16
    evaluator = Evaluator(criteria=("visibility", "roi"), measures=("bmp",))
    roi = np.zeros((4, 6), bool)
    masks = {"nonocc": np.ones((4, 6), bool)}
    assert evaluator.score(gt, gt, masks=masks, roi=roi)["roi"]["n"] == 0
    roi[:2] = True
    assert evaluator.score(gt, gt, masks=masks, roi=roi)["roi"]["n"] == 12


def test_cache_hits_by_bit_pattern_newest_first(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(5)
    maps = [rng.uniform(1, 30, (6, 7)).astype(np.float32) for _ in range(5)]
    maps[0][0, :3] = np.nan  # NaN GT values: bit-equal copies still hit the cache
    est = maps[0] + 1.0
    evaluator = Evaluator(criteria=("all", "depth"), cache_size=4)
    built: list[int] = []
    original = evaluator.reference

    def counting(gt: np.ndarray, *args: object, **kwargs: object) -> object:
        built.append(1)
        return original(gt, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(evaluator, "reference", counting)
    first = [evaluator.score(gt, est).sums for gt in maps[:4]]
    assert len(built) == 4
    again = [evaluator.score(gt.copy(), est).sums for gt in maps[:4]]  # equal content, new objects
    assert len(built) == 4
    for a, b in zip(first, again, strict=True):
        np.testing.assert_array_equal(a, b)
    # maps[0] was used last-but-three: a fifth map evicts the least recently used (maps[1])
    evaluator.score(maps[0], est)
    evaluator.score(maps[4], est)
    assert len(built) == 5
    evaluator.score(maps[0], est)
    assert len(built) == 5
    evaluator.score(maps[1], est)
    assert len(built) == 6
    # -0.0 differs from 0.0 in bits only: a rebuilt reference with the same scores
    zeros = maps[2].copy()
    zeros[1, :] = 0.0
    plus = evaluator.score(zeros, est).sums
    minus = evaluator.score(np.where(zeros == 0, np.float32(-0.0), zeros), est).sums
    np.testing.assert_array_equal(plus, minus)
