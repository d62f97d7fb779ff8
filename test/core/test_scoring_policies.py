"""Missing estimates: est_range, the kinds of missing values and the three policies
(KITTI interpolation, thesis, ignore).

Conventions of the code under test: reference.py (METHOD.md §1–3).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from reference import (
    POLICIES,
    kitti_fill,
)
from scoring_support import INF, NAN

from dispeval_ros.core.evaluator import Evaluator


def test_est_range_is_inclusive_and_outside_is_missing() -> None:
    gt = np.full((1, 4), 10.0, np.float32)
    est = np.array([[2.0, 64.0, 1.5, 64.5]], np.float32)  # range (2, 64): last two missing
    got = Evaluator(criteria=("all",), missing="thesis").score(gt, est, est_range=(2.0, 64.0))
    assert got["all"]["density"] == 0.5
    # thesis: e = 8, 54, 10, 10
    assert got["all"]["mae"] == pytest.approx((8 + 54 + 10 + 10) / 4)
    # without a range every positive finite value is valid
    unbounded = Evaluator(criteria=("all",), missing="thesis").score(gt, est)
    assert unbounded["all"]["density"] == 1.0


@settings(max_examples=150, deadline=None)
@given(
    bounds=st.tuples(
        st.floats(allow_nan=True, allow_infinity=True, width=64),
        st.floats(allow_nan=True, allow_infinity=True, width=64),
    ),
    policy=st.sampled_from(POLICIES),
)
@example(bounds=(-INF, INF), policy="thesis")
@example(bounds=(0.1, 0.3), policy="interpolate")
def test_est_range_selects_exactly_the_float32_values_within_float64_bounds(
    bounds: tuple[float, float], policy: str
) -> None:
    """The kernels compare float32 estimates with float32 bounds: the same values must pass.

    The estimates are each bound's float32 neighbours (and 0, inf, nan); density counts
    those with ``lo <= v <= hi`` (compared in float64; 0 and negative values included, as a
    DisparityImage's range defines) and ``v`` finite, and ``0 < v`` when ``lo`` is −inf.
    """
    lo, hi = bounds
    candidates = [0.0, 1e-45, 1.0, INF, NAN, np.finfo(np.float32).max]
    for bound in (lo, hi):
        if math.isfinite(bound) and abs(bound) < 3e38:
            near = np.float32(bound)
            candidates += [near, np.nextafter(near, np.float32(INF)), np.nextafter(near, -INF)]
    est = np.array([candidates], np.float32)
    values = est.astype(np.float64)[0]
    with np.errstate(invalid="ignore"):
        expected = (values >= lo) & (values <= hi) & np.isfinite(values)
        if lo == -INF:
            expected &= values > 0
    gt = np.ones_like(est)
    got = Evaluator(criteria=("all",), missing=policy).score(gt, est, est_range=(lo, hi))
    assert got["all"]["density"] == np.count_nonzero(expected) / est.size


def test_missing_kinds_nan_inf_zero_negative() -> None:
    gt = np.full((1, 5), 4.0, np.float32)
    est = np.array([[NAN, INF, 0.0, -3.0, 4.0]], np.float32)
    for policy in ("thesis", "ignore"):
        got = Evaluator(criteria=("all",), missing=policy).score(gt, est)["all"]
        assert got["density"] == 0.2
        assert got["n"] == 5
    assert Evaluator(criteria=("all",), missing="thesis").score(gt, est)["all"]["mae"] == 3.2
    assert Evaluator(criteria=("all",), missing="ignore").score(gt, est)["all"]["mae"] == 0.0


def test_ignore_with_no_valid_estimate_gives_nan_not_zero() -> None:
    gt = np.full((2, 2), 4.0, np.float32)
    est = np.zeros((2, 2), np.float32)
    got = Evaluator(criteria=("all",), missing="ignore").score(gt, est)["all"]
    assert got["n"] == 4
    assert got["density"] == 0.0
    for measure in ("bmp", "mae", "rmse", "mre", "sze_mean", "d1", "a50"):
        assert math.isnan(got[measure]), measure
    assert got["sze"] == 0.0
    assert got["bmp_count"] == 0.0


# ------------------------------------------------------------------------- KITTI interpolation


def library_estimate(est: np.ndarray, policy: str = "interpolate", est_range=None) -> np.ndarray:
    """The estimate as scoring sees it, recovered through public scores only.

    Every pixel is its own named ROI class and the GT is 1000 everywhere, so each
    criterion's ``mae`` is ``1000 − E`` (all test values are ≤ 1000); NaN under ``ignore``.
    """
    height, width = est.shape
    labels = np.arange(height * width).reshape(height, width) + 1
    evaluator = Evaluator(
        criteria=("roi",),
        measures=("mae",),
        missing=policy,
        roi_names={int(i): f"p{i}" for i in labels.ravel()},
    )
    gt = np.full(est.shape, 1000.0, np.float32)
    scores = evaluator.score(gt, est, roi=labels, est_range=est_range)
    return np.array([1000.0 - scores[f"p{i}"]["mae"] for i in labels.ravel()]).reshape(est.shape)


def test_interpolation_rows_gaps_and_copied_rows() -> None:
    est = np.array(
        [
            [NAN, NAN, NAN, NAN, NAN, NAN],  # above the first row with values: copies row 1
            [NAN, 5.0, NAN, NAN, 3.0, NAN],  # leading 5; gap between 5 and 3 → 3; trailing 3
            [0.0, -1.0, NAN, INF, 0.0, NAN],  # all missing, between valid rows: E = 0
            [7.0, NAN, 9.0, 0.0, -1.0, 2.0],  # gap 7|9 → 7; gap 9|2 → 2
            [NAN, NAN, NAN, NAN, NAN, NAN],  # below the last row with values: copies row 3
            [INF, 0.0, -2.0, NAN, NAN, NAN],  # likewise
        ],
        np.float32,
    )
    expected = np.array(
        [
            [5, 5, 3, 3, 3, 3],
            [5, 5, 3, 3, 3, 3],
            [0, 0, 0, 0, 0, 0],
            [7, 7, 9, 2, 2, 2],
            [7, 7, 9, 2, 2, 2],
            [7, 7, 9, 2, 2, 2],
        ],
        np.float64,
    )
    np.testing.assert_array_equal(library_estimate(est), expected)
    # the independent re-computation used by the property tests agrees
    valid = np.isfinite(est) & (est > 0)
    np.testing.assert_array_equal(kitti_fill(np.where(valid, est, 0.0), valid), expected)


def test_interpolation_takes_the_smaller_neighbour_either_side() -> None:
    est = np.array([[2.0, NAN, NAN, 9.0, NAN, 4.0]], np.float32)
    np.testing.assert_array_equal(library_estimate(est), [[2, 2, 2, 9, 4, 4]])


def test_interpolation_respects_est_range_and_other_policies() -> None:
    est = np.array([[70.0, 6.0, 80.0, 5.0, 90.0]], np.float32)  # range (1, 64): 70, 80, 90 out
    np.testing.assert_array_equal(library_estimate(est, est_range=(1, 64)), [[6, 6, 5, 5, 5]])
    np.testing.assert_array_equal(
        library_estimate(est, "thesis", est_range=(1, 64)), [[0, 6, 0, 5, 0]]
    )
    ignored = library_estimate(est, "ignore", est_range=(1, 64))
    np.testing.assert_array_equal(np.isnan(ignored), [[True, False, True, False, True]])


def test_interpolation_of_an_all_missing_estimate_is_zero() -> None:
    est = np.full((3, 4), NAN, np.float32)
    np.testing.assert_array_equal(library_estimate(est), np.zeros((3, 4)))


def test_density_counts_before_interpolation_per_criterion() -> None:
    gt = np.full((2, 4), 5.0, np.float32)
    est = np.array([[5, NAN, NAN, 5], [NAN, NAN, NAN, NAN]], np.float32)
    roi = np.array([[1, 1, 0, 0], [0, 0, 0, 0]])
    scores = Evaluator(criteria=("all", "roi")).score(gt, est, roi=roi)
    assert scores["all"]["density"] == 2 / 8
    assert scores["roi"]["density"] == 1 / 2
    assert scores["elsewhere"]["density"] == 1 / 6
    assert scores["all"]["mae"] == 0.0  # everything interpolated to 5
