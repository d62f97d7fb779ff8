"""Combining scores of several frames: sums of sums, rejections of mixed inputs.

Conventions of the code under test: reference.py (METHOD.md §1–3).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference import (
    POLICIES,
)
from scoring_support import NAN, one_line

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.evaluator import Evaluator
from dispeval_ros.core.measures import DEFAULT_MEASURES, Scores
from dispeval_ros.errors import (
    ConfigurationError,
)

QUANTILES = ("a50", "a90", "a95", "a99")
"""Order statistics: not combinable from sums, so left out of the sums-of-sums check."""


def test_combine_is_sums_of_sums_not_mean_of_means() -> None:
    evaluator = Evaluator(criteria=("all",), missing="thesis")
    # frame A: 2 points, errors 4, 0 → mae 2; frame B: 6 points, all exact → mae 0
    a = evaluator.score(np.full((1, 2), 10.0, np.float32), np.array([[14, 10]], np.float32))
    b = evaluator.score(np.full((2, 3), 10.0, np.float32), np.full((2, 3), 10.0, np.float32))
    both = Scores.combine([a, b])
    assert both["all"]["n"] == 8
    assert both["all"]["mae"] == 0.5  # 4 / 8, not (2 + 0) / 2
    assert both["all"]["bmp"] == 12.5
    assert both["all"]["mse"] == 2.0  # 16 / 8
    assert both["all"]["sze"] == pytest.approx(a["all"]["sze"] + b["all"]["sze"])
    assert math.isnan(both["all"]["a50"])  # quantiles are not summable


@pytest.mark.parametrize("policy", POLICIES)
def test_combine_equals_scoring_the_concatenated_frames(policy: str) -> None:
    """Frames stacked vertically score like their combination.

    Every row has a valid estimate (so interpolation stays within rows) and visibility comes
    from official masks (row-local), so stacking changes nothing but the totals.
    """
    rng = np.random.default_rng(7)
    evaluator = Evaluator(criteria=("all", "visibility", "roi"), missing=policy)
    camera = Camera(f=500.0, baseline=0.2)
    parts, frames = [], []
    for height in (5, 7, 4):
        gt = rng.uniform(1, 40, (height, 9)).astype(np.float32)
        gt[rng.random(gt.shape) < 0.15] = 0
        est = (gt + rng.normal(0, 2, gt.shape)).astype(np.float32)
        est[rng.random(gt.shape) < 0.2] = NAN
        est[:, 0] = 20.0
        masks = {"nonocc": rng.random(gt.shape) < 0.8, "disc": rng.random(gt.shape) < 0.3}
        roi = rng.random(gt.shape) < 0.5
        parts.append(evaluator.score(gt, est, camera, masks=masks, roi=roi))
        frames.append((gt, est, masks, roi))
    combined = Scores.combine(parts)
    stacked = evaluator.score(
        np.vstack([f[0] for f in frames]),
        np.vstack([f[1] for f in frames]),
        camera,
        masks={k: np.vstack([f[2][k] for f in frames]) for k in ("nonocc", "disc")},
        roi=np.vstack([f[3] for f in frames]),
    )
    np.testing.assert_allclose(combined.sums, stacked.sums, rtol=1e-9)
    for criterion in stacked:
        for measure in set(DEFAULT_MEASURES) - set(QUANTILES) | {"n"}:
            want, have = stacked[criterion][measure], combined[criterion][measure]
            assert have == pytest.approx(want, rel=1e-9, nan_ok=True), (criterion, measure)


def test_combine_rejects_mixed_policies_and_units() -> None:
    gt = np.full((2, 2), 4.0, np.float32)
    est = np.array([[4.0, NAN], [5.0, 4.0]], np.float32)
    ignore = Evaluator(criteria=("all",), missing="ignore").score(gt, est)
    thesis = Evaluator(criteria=("all",), missing="thesis").score(gt, est)
    with pytest.raises(ConfigurationError):
        Scores.combine([ignore, thesis])
    metric = Evaluator(criteria=("all",)).score(gt, est, Camera(f=700.0, baseline=0.5))
    relative = Evaluator(criteria=("all",)).score(gt, est)
    with pytest.raises(ConfigurationError):
        Scores.combine([metric, relative])


def test_combine_rejects_nothing_and_mismatched_criteria() -> None:
    gt = np.full((2, 2), 3.0, np.float32)
    a = Evaluator(criteria=("all",)).score(gt, gt)
    b = Evaluator(criteria=("all", "depth")).score(gt, gt)
    with pytest.raises(ConfigurationError) as empty:
        Scores.combine([])
    one_line(empty)
    with pytest.raises(ConfigurationError) as mixed:
        Scores.combine([a, b])
    one_line(mixed)
