"""Scoring measures: the hand-worked example of every measure, δ, d1 and SZE.

Conventions of the code under test: reference.py (METHOD.md §1–3).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference import (
    POLICIES,
    assert_matches,
    numpy_measures,
)
from scoring_support import EST_HAND, GT_HAND, NAN, RANGE_HAND

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.evaluator import Evaluator
from dispeval_ros.core.measures import DEFAULT_MEASURES

# The hand-worked example (its maps GT_HAND, EST_HAND, RANGE_HAND are in scoring_support.py):
#
# GT (3×4), "." = invalid GT (0 or NaN):        estimate, est_range = (1, 50):
#   2    4     8   .                             3       4    8   7
#   10   10    10  10                            11.125  nan  10  60 (> 50: missing)
#   5    .     20  40                            5       9    16  0 (missing)
#
# valid GT: 10 points; valid estimates among them: 7 → density 0.7.
# e at the valid-GT points (row-major), δ = 1:
#   (0,0) |3-2| = 1 exactly δ (not bad); (1,0) |11.125-10| = 1.125 just above δ (bad);
#   (0,1) (0,2) (1,2) (2,0) e = 0; (2,2) |16-20| = 4;
#   missing: (1,1) D=10, (1,3) D=10, (2,3) D=40.


def sze_terms(pairs: list[tuple[float, float]], fb: float = 1.0, doffs: float = 0.0) -> float:
    """Σ |fb/(D+doffs+μ) − fb/(E+doffs+μ)| over (D, E) pairs, μ = 0.01."""
    return sum(abs(fb / (d + doffs + 0.01) - fb / (e + doffs + 0.01)) for d, e in pairs)


# thesis: missing → E = 0, so e = 10, 10, 40 there.
#   errors: 1, 0, 0, 1.125, 10, 0, 10, 0, 4, 40 → Σe = 66.125, Σe² = 1818.265625
#   e/D:    .5, 0, 0, .1125, 1, 0, 1, 0, .2, 1   → Σ = 3.8125
#   bad (e > 1): 1.125, 10, 10, 4, 40 → 5; e > 0.5: 6; e > 2: 4; e > 4: 3 (4 is not > 4)
#   bmpre = .1125 + 1 + 1 + .2 + 1 = 3.3125
#   d1 (e > 3 and e > D/20): 10, 10, 4, 40 → 4
#   sorted errors 0,0,0,0,1,1.125,4,10,10,40: a50 = [5] = 1.125; a90 = a95 = a99 = [9] = 40
THESIS_PAIRS = [(2, 3), (4, 4), (8, 8), (10, 11.125), (10, 0), (10, 10), (10, 0), (5, 5),
                (20, 16), (40, 0)]  # fmt: skip
# interpolate: row 1 → 11.125, [min(11.125, 10) = 10], 10, [trailing: 10];
#              row 2 → 5, 9, 16, [trailing: 16]
#   errors: 1, 0, 0, 1.125, 0, 0, 0, 0, 4, 24 → Σe = 30.125, Σe² = 594.265625
#   e/D: .5, .1125, .2, .6 → Σ = 1.4125; bad: 1.125, 4, 24 → 3; e > .5: 4; > 2: 2; > 4: 1
#   bmpre = .1125 + .2 + .6 = .9125; d1: 4, 24 → 2
#   sorted 0 ×6, 1, 1.125, 4, 24: a50 = [5] = 0; a90 = [9] = 24
INTERP_PAIRS = [(2, 3), (4, 4), (8, 8), (10, 11.125), (10, 10), (10, 10), (10, 10), (5, 5),
                (20, 16), (40, 16)]  # fmt: skip
# ignore: only the 7 valid estimates: errors 1, 0, 0, 1.125, 0, 0, 4 → Σe = 6.125,
#   Σe² = 18.265625, Σ e/D = .5 + .1125 + .2 = .8125; bad: 1.125, 4 → 2; > .5: 3; > 2: 1;
#   > 4: 0; bmpre = .3125; d1: 4 → 1; sorted 0,0,0,0,1,1.125,4: a50 = [3] = 0; a90 = [6] = 4
IGNORE_PAIRS = [(2, 3), (4, 4), (8, 8), (10, 11.125), (10, 10), (5, 5), (20, 16)]

HAND_EXPECTED = {
    "thesis": {
        "n": 10, "density": 0.7, "bmp": 50.0, "bmp_count": 5, "bad_0.5": 60.0, "bad_2": 40.0,
        "bad_4": 30.0, "mae": 6.6125, "mse": 181.8265625, "rmse": math.sqrt(181.8265625),
        "mre": 0.38125, "bmpre": 3.3125, "bmpre_mean": 0.33125, "d1": 40.0,
        "sze": sze_terms(THESIS_PAIRS), "sze_mean": sze_terms(THESIS_PAIRS) / 10,
        "a50": 1.125, "a90": 40.0, "a95": 40.0, "a99": 40.0,
    },
    "interpolate": {
        "n": 10, "density": 0.7, "bmp": 30.0, "bmp_count": 3, "bad_0.5": 40.0, "bad_2": 20.0,
        "bad_4": 10.0, "mae": 3.0125, "mse": 59.4265625, "rmse": math.sqrt(59.4265625),
        "mre": 0.14125, "bmpre": 0.9125, "bmpre_mean": 0.09125, "d1": 20.0,
        "sze": sze_terms(INTERP_PAIRS), "sze_mean": sze_terms(INTERP_PAIRS) / 10,
        "a50": 0.0, "a90": 24.0, "a95": 24.0, "a99": 24.0,
    },
    "ignore": {
        "n": 10, "density": 0.7, "bmp": 200 / 7, "bmp_count": 2, "bad_0.5": 300 / 7,
        "bad_2": 100 / 7, "bad_4": 0.0, "mae": 6.125 / 7, "mse": 18.265625 / 7,
        "rmse": math.sqrt(18.265625 / 7), "mre": 0.8125 / 7, "bmpre": 0.3125,
        "bmpre_mean": 0.3125 / 7, "d1": 100 / 7, "sze": sze_terms(IGNORE_PAIRS),
        "sze_mean": sze_terms(IGNORE_PAIRS) / 7, "a50": 0.0, "a90": 4.0, "a95": 4.0, "a99": 4.0,
    },
}  # fmt: skip


@pytest.mark.parametrize("policy", POLICIES)
def test_hand_example_every_measure(policy: str) -> None:
    scores = Evaluator(criteria=("all",), missing=policy).score(
        GT_HAND, EST_HAND, est_range=RANGE_HAND
    )
    assert scores.policy == policy
    assert scores.relative  # no camera: f·B = 1
    got = scores["all"]
    expected = HAND_EXPECTED[policy]
    assert set(DEFAULT_MEASURES) | {"n"} == set(got)
    for measure, want in expected.items():
        assert got[measure] == pytest.approx(want, rel=1e-6, abs=1e-12), measure


@pytest.mark.parametrize("policy", POLICIES)
def test_hand_example_equals_numpy_recomputation(policy: str) -> None:
    valid = np.isfinite(GT_HAND) & (GT_HAND > 0)
    scores = Evaluator(criteria=("all",), missing=policy).score(
        GT_HAND, EST_HAND, est_range=RANGE_HAND
    )
    expected = numpy_measures(GT_HAND, EST_HAND, {"all": valid}, policy, est_range=RANGE_HAND)
    assert_matches(scores, expected)


def test_delta_boundary_and_other_delta() -> None:
    """e = δ exactly is not bad, e just above is; δ is configurable and feeds bmpre too."""
    gt = np.array([[2.5, 2.5, 2.5, 8.0]], np.float32)
    est = np.array([[3.5, 3.625, 2.5, 8.5]], np.float32)  # e = 1, 1.125, 0, 0.5 (exact floats)
    got = Evaluator(criteria=("all",), missing="thesis").score(gt, est)["all"]
    assert got["bmp_count"] == 1
    assert got["bmp"] == 25.0
    assert got["bmpre"] == pytest.approx(1.125 / 2.5)
    half = Evaluator(criteria=("all",), missing="thesis", delta=0.5).score(gt, est)["all"]
    # δ = 0.5: e = 1 and 1.125 are bad, e = 0.5 is not
    assert half["bmp_count"] == 2
    assert half["bmpre"] == pytest.approx(1 / 2.5 + 1.125 / 2.5)


def test_d1_needs_both_conditions() -> None:
    # e = 4 with D = 80 (exactly 5 %: no), 4.5 with D = 80 (yes), 3.5 with D = 10 (yes),
    # 3 with D = 100 (not > 3: no) → d1 = 50 %
    gt = np.array([[80.0, 80.0, 10.0, 100.0]], np.float32)
    est = np.array([[84.0, 84.5, 13.5, 103.0]], np.float32)
    assert Evaluator(criteria=("all",)).score(gt, est)["all"]["d1"] == 50.0


# --------------------------------------------------------------------------------------- SZE


def test_sze_with_camera_uses_f_baseline_doffs() -> None:
    # f·B = 100·0.5 = 50, doffs = 2, μ = 0.01; thesis: the hole scores E = 0
    #   |50/12.01 − 50/14.01| ≈ 0.59431, |50/22.01 − 50/2.01| ≈ 22.60392, 0 → ≈ 23.19824
    camera = Camera(f=100.0, baseline=0.5, doffs=2.0)
    gt = np.array([[10.0, 20.0, 40.0]], np.float32)
    est = np.array([[12.0, NAN, 40.0]], np.float32)
    scores = Evaluator(criteria=("all",), missing="thesis").score(gt, est, camera)
    expected = 50 / 12.01 - 50 / 14.01 + 50 / 2.01 - 50 / 22.01
    assert expected == pytest.approx(23.19824, abs=1e-5)
    assert not scores.relative
    assert scores["all"]["sze"] == pytest.approx(expected, rel=1e-9)
    assert scores["all"]["sze_mean"] == pytest.approx(expected / 3, rel=1e-9)


def test_sze_without_camera_is_relative() -> None:
    gt = np.array([[10.0, 20.0]], np.float32)
    est = np.array([[12.0, 20.0]], np.float32)
    scores = Evaluator(criteria=("all",)).score(gt, est)
    assert scores.relative
    assert scores["all"]["sze"] == pytest.approx(1 / 10.01 - 1 / 12.01, rel=1e-9)


def test_sze_guard_mu_is_configurable() -> None:
    gt = np.array([[10.0]], np.float32)
    est = np.array([[NAN]], np.float32)
    scores = Evaluator(criteria=("all",), missing="thesis", mu=0.5).score(gt, est)
    assert scores["all"]["sze"] == pytest.approx(1 / 0.5 - 1 / 10.5, rel=1e-9)
