"""Criteria: all, official masks, visibility, depth, metric ranges, ROI, legacy, reference.

Conventions of the code under test: reference.py (METHOD.md §1–3).
"""

from __future__ import annotations

import math

import numpy as np
from scoring_support import EST_HAND, GT_HAND, INF, NAN

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.evaluator import Evaluator


def test_all_criterion_counts_valid_points_only() -> None:
    gt = np.array([[1, 0, NAN], [INF, -2, 3]], np.float32)
    partition = Evaluator(criteria=("all",)).reference(gt).partition
    assert partition.counts() == {"all": 2}
    np.testing.assert_array_equal(partition.mask("all"), [[1, 0, 0], [0, 0, 1]])


def test_official_all_mask_restricts_valid_points() -> None:
    gt = np.full((2, 3), 4.0, np.float32)
    all_mask = np.array([[1, 1, 0], [0, 1, 1]], bool)
    scores = Evaluator(criteria=("all",)).score(gt, gt, masks={"all": all_mask})
    assert scores["all"]["n"] == 4


def test_visibility_from_official_masks() -> None:
    # valid everywhere but (0,0); nonocc excludes column 3; disc = column 2 (and (0,3),
    # which is occluded and so stays occluded)
    gt = np.full((2, 4), 6.0, np.float32)
    gt[0, 0] = 0
    nonocc = np.array([[1, 1, 1, 0], [1, 1, 1, 0]], bool)
    disc = np.array([[0, 0, 1, 1], [0, 0, 1, 0]], bool)
    partition = (
        Evaluator(criteria=("visibility",))
        .reference(gt, masks={"nonocc": nonocc, "disc": disc})
        .partition
    )
    assert partition.counts() == {"occluded": 2, "boundary": 2, "interior": 3}
    np.testing.assert_array_equal(partition.mask("occluded"), ~nonocc)


def test_visibility_left_right_check_with_right_gt() -> None:
    # left row of 2s: x = 0, 1 land outside; x = 2 → right[0] = 2 agrees; x = 3 → right[1] = 5
    # disagrees by 3 > 1 → occluded = {0, 1, 3}
    gt = np.full((1, 4), 2.0, np.float32)
    right = np.array([[2.0, 5.0, 2.0, 2.0]], np.float32)
    evaluator = Evaluator(criteria=("visibility",))
    partition = evaluator.reference(gt, gt_right=right).partition
    np.testing.assert_array_equal(partition.mask("occluded"), [[1, 1, 0, 1]])
    # an official mask takes precedence over the right GT
    nonocc = np.ones((1, 4), bool)
    both = evaluator.reference(gt, masks={"nonocc": nonocc}, gt_right=right).partition
    assert both.counts()["occluded"] == 0


def test_left_right_check_rounds_like_c_and_rejects_unknown_right_values() -> None:
    """MiddEval3's computemask: C ``round`` (x − d = −0.5 → −1) and unknown right GT mismatches.

    x=0, d=0.5: −0.5 rounds to −1, outside (rounding half up would land on right[0] = 0.5
    and agree). x=1, d=2: −1, outside. x=2, d=1: right[1] = 0 is unknown (as 0 it would
    agree within 1). x=3, d=1.5: 1.5 rounds to 2, right[2] = 2 agrees. x=4, d=1: right[3]
    is inf, unknown. x=5, d=1: right[4] is NaN, unknown.
    """
    gt = np.array([[0.5, 2.0, 1.0, 1.5, 1.0, 1.0]], np.float32)
    right = np.array([[0.5, 0.0, 2.0, np.inf, np.nan, 1.0]], np.float32)
    partition = Evaluator(criteria=("visibility",)).reference(gt, gt_right=right).partition
    np.testing.assert_array_equal(partition.mask("occluded"), [[1, 1, 1, 0, 1, 1]])


def test_visibility_zbuffer_and_discontinuities_by_hand() -> None:
    # two identical rows, 14 columns, boundary width 3:
    #   d:       2 2 2 2 2 2 6 6 2 2 2  2  2  .(0)
    #   x − d:  -2 -1 0 1 2 3 0 1 6 7 8  9 10
    # x = 0, 1 land outside; x = 2, 3 land on 0, 1 where the 6s (x = 6, 7) land too → hidden.
    # jumps > 2: between x = 5|6 and 7|8 (the 2|invalid edge at 12|13 is no jump);
    # ±1 dilation → x = 4..9 boundary; interior x = 10..12.
    row = [2, 2, 2, 2, 2, 2, 6, 6, 2, 2, 2, 2, 2, 0]
    gt = np.array([row, row], np.float32)
    partition = Evaluator(criteria=("visibility",), boundary_width=3).reference(gt).partition
    assert partition.counts() == {"occluded": 8, "boundary": 12, "interior": 6}
    np.testing.assert_array_equal(np.flatnonzero(partition.mask("occluded")[0]), [0, 1, 2, 3])
    np.testing.assert_array_equal(np.flatnonzero(partition.mask("boundary")[0]), range(4, 10))
    # the gap option: with gap 4 the jump of exactly 4 is no discontinuity
    wide = Evaluator(criteria=("visibility",), boundary_width=3, boundary_gap=4.0)
    assert wide.reference(gt).partition.counts()["boundary"] == 0
    # the occlusion tolerance: a 6 in front of a 2 hides it unless the tolerance is ≥ 4
    loose = Evaluator(criteria=("visibility",), boundary_width=3, occlusion_tolerance=4.0)
    assert loose.reference(gt).partition.counts()["occluded"] == 4


def test_depth_three_means_by_hand_with_a_tie() -> None:
    # values 1 2 3 4 7: plain Lloyd from 2, 4, 6 stops at far {1,2,3}, mid {4}, near {7}
    # (within-cluster SSE 2), but the optimum is far {1,2}, mid {3,4}, near {7} (SSE 0.5 + 0.5
    # = 1): centroids 1.5, 3.5, 7 → thresholds 2.5, 5.25, a Lloyd fixed point.
    gt = np.array([[1, 2, 3], [4, 7, 0]], np.float32)
    partition = Evaluator(criteria=("depth",)).reference(gt).partition
    assert {c: sorted(gt[partition.mask(c)].tolist()) for c in ("near", "mid", "far")} == {
        "near": [7.0],
        "mid": [3.0, 4.0],
        "far": [1.0, 2.0],
    }


def test_metric_depth_ranges() -> None:
    # f·B = 100, doffs = 0: d = 20, 10, 5, 2 → Z = 5, 10, 20, 50. Ranges are [from, to):
    # Z = 10 is in 10–30; the invalid 0 is in none.
    camera = Camera(f=100.0, baseline=1.0)
    evaluator = Evaluator(criteria=("depth",), depth_ranges=[(0, 10), (10, 30), (30, math.inf)])
    gt = np.array([[20, 10, 5, 2, 0]], np.float32)
    partition = evaluator.reference(gt, camera).partition
    assert partition.criteria == ("0-10m", "10-30m", "30+m")
    assert partition.counts() == {"0-10m": 1, "10-30m": 2, "30+m": 1}
    # doffs shifts depth: Z = 100/(d + 5) → 4, 6.67, 10, 14.3
    shifted = evaluator.reference(gt, Camera(f=100.0, baseline=1.0, doffs=5.0)).partition
    assert shifted.counts() == {"0-10m": 2, "10-30m": 2, "30+m": 0}
    scores = evaluator.score(gt, gt, camera)
    assert scores["30+m"]["n"] == 1


def test_roi_mask_and_named_label_image() -> None:
    gt = np.full((2, 4), 5.0, np.float32)
    gt[1, 3] = NAN
    mask = np.array([[1, 1, 0, 0], [0, 0, 0, 1]], np.uint8)
    counts = Evaluator(criteria=("roi",)).reference(gt, roi=mask).partition.counts()
    assert counts == {"roi": 2, "elsewhere": 5}
    labels = np.array([[0, 1, 2, 3], [1, 1, 2, 2]])
    named = Evaluator(criteria=("roi",), roi_names={1: "road", 2: "car"})
    partition = named.reference(gt, roi=labels).partition
    assert partition.criteria == ("road", "car", "unlabelled")
    assert partition.counts() == {"road": 3, "car": 2, "unlabelled": 2}
    est = gt.copy()
    est[0, 1] = 9.0  # a road error
    scores = named.score(gt, est, roi=labels)
    assert scores["road"]["bmp_count"] == 1
    assert scores["car"]["bmp_count"] == 0


def test_legacy_criteria_overlap() -> None:
    # 2×4, valid everywhere: nonocc = all but column 0; disc = column 1
    gt = np.full((2, 4), 8.0, np.float32)
    nonocc = np.array([[0, 1, 1, 1], [0, 1, 1, 1]], bool)
    disc = np.array([[0, 1, 0, 0], [0, 1, 0, 0]], bool)
    est = gt.copy()
    est[0, 0] = 20.0  # occluded error
    est[0, 1] = 20.0  # disc error
    est[1, 3] = 20.0  # interior error
    evaluator = Evaluator(criteria=("legacy",))
    scores = evaluator.score(gt, est, masks={"nonocc": nonocc, "disc": disc})
    assert scores.overlapping == ("nonocc", "all", "disc")
    assert {c: scores[c]["n"] for c in scores} == {"nonocc": 6, "all": 8, "disc": 2}
    assert {c: scores[c]["bmp_count"] for c in scores} == {"nonocc": 2, "all": 3, "disc": 1}
    # the counts add up to more than the valid points: they overlap
    assert sum(scores[c]["n"] for c in scores) > 8
    both = Evaluator(criteria=("all", "visibility", "legacy")).score(
        gt, est, masks={"nonocc": nonocc, "disc": disc}
    )
    assert both["nonocc"]["n"] == both["boundary"]["n"] + both["interior"]["n"]
    assert both["disc"]["bmp_count"] == both["boundary"]["bmp_count"]
    assert both.overlapping == ("nonocc", "disc")  # "all" is shared with the partitioning set


def test_reference_object_scores_like_the_gt() -> None:
    evaluator = Evaluator()
    reference = evaluator.reference(GT_HAND)
    a = evaluator.score(reference, EST_HAND)
    b = evaluator.score(GT_HAND, EST_HAND)
    np.testing.assert_array_equal(a.sums, b.sums)
    assert a.to_dict().keys() == b.to_dict().keys()
