"""Tests of the scoring engine: measures, missing-estimate policies, criteria and the cache.

Conventions of the code under test that these tests rely on (METHOD.md §1–3):

- valid GT = finite and > 0, restricted to an official ``all`` mask when one is given;
- missing estimate = not finite, ≤ 0, or outside ``est_range`` (inclusive ``[lo, hi]``);
- ``interpolate`` = KITTI background interpolation (a gap between two valid estimates of a row
  takes the smaller neighbour, a leading gap the first valid value, a trailing gap the last;
  rows above the first / below the last row with any valid value copy that row; still
  missing → E = 0), ``thesis`` = E = 0 for missing, ``ignore`` = missing points left out of
  every error measure but counted in ``n`` and ``density``;
- per criterion: ``n`` = valid-GT points, ``density`` = valid estimates (before interpolation)
  / n, N_eval = n except under ``ignore`` (number of valid estimates); bmp/bad_X/d1 are
  percentages of N_eval; mae, mse, rmse, mre are means over N_eval; sze and bmpre are sums,
  sze_mean and bmpre_mean these sums / N_eval; aNN = sorted errors at index ⌊N_eval·q/100⌋;
- errors are computed in float64 from the float32 maps: ``e = |float64(E) − float64(D)|``;
- SZE = Σ|f·B/(D + doffs + μ) − f·B/(E + doffs + μ)| (f·B = 1, doffs = 0 without a camera,
  flagged ``scores.relative``);
- visibility: occluded from the official ``nonocc`` mask, else a left-right check with the
  right GT, else z-buffer forward warping (target column ``floor(x − d + 0.5)``, i.e. round
  half up); boundary = the ``disc`` mask, else points within a ``width`` square of a
  4-neighbour jump > ``gap`` between two valid points, minus occluded; interior = the rest;
- depth: deterministic 3-means (Lloyd to a fixed point, started from the optimal split of a
  fine histogram; a value equal to a threshold goes to the farther cluster), ``near`` =
  largest disparities; metric ranges are half-open ``[from, to)`` in depth ``Z = f·B/(d + doffs)``.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from reference import (
    POLICIES,
    assert_matches,
    kitti_fill,
    near_jumps,
    numpy_measures,
    zbuffer_occlusion,
)

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.evaluator import Evaluator, kth_smallest
from dispeval_ros.core.measures import DEFAULT_MEASURES, Scores
from dispeval_ros.errors import (
    ConfigurationError,
    EmptyGroundTruthError,
    InputError,
    ShapeMismatchError,
)

NAN = math.nan
INF = math.inf
# measures compared with rtol 1e-9 (counts, percentages, order statistics; reference.SUMS 1e-6)
EXACT = ("n", "bmp", "bmp_count", "bad_0.5", "bad_2", "bad_4", "d1", "density")
QUANTILES = ("a50", "a90", "a95", "a99")


def one_line(error: pytest.ExceptionInfo[BaseException]) -> str:
    message = str(error.value)
    assert message, "empty error message"
    assert "\n" not in message, f"multi-line message: {message!r}"
    return message


# ------------------------------------------------------------------------ hand-worked example
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
GT_HAND = np.array([[2, 4, 8, 0], [10, 10, 10, 10], [5, NAN, 20, 40]], np.float32)
EST_HAND = np.array([[3, 4, 8, 7], [11.125, NAN, 10, 60], [5, 9, 16, 0]], np.float32)
RANGE_HAND = (1.0, 50.0)


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


# --------------------------------------------------------------------------------- quantiles


def test_quantiles_at_floor_index_without_interpolation() -> None:
    # 10 errors 0..9 (GT 100, E = 100 + i): a50 = sorted[5] = 5, a90 = sorted[9] = 9;
    # a75 = sorted[⌊7.5⌋] = 7 (an interpolating quantile would give 6.75)
    gt = np.full((2, 5), 100.0, np.float32)
    est = (100.0 + np.arange(10, dtype=np.float32)[::-1]).reshape(2, 5)
    got = Evaluator(criteria=("all",), measures=("a50", "a90", "a75", "a10")).score(gt, est)
    assert got["all"]["a50"] == 5.0
    assert got["all"]["a90"] == 9.0
    assert got["all"]["a75"] == 7.0
    assert got["all"]["a10"] == 1.0


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.lists(st.integers(0, 40).map(lambda v: v / 4), max_size=300).map(sorted),
        min_size=1,
        max_size=9,
    ),
    st.data(),
)
def test_kth_smallest_of_sorted_parts_is_the_sorted_union(
    parts: list[list[float]], data: st.DataObject
) -> None:
    union = np.sort(np.concatenate([np.asarray(p, dtype=np.float64) for p in parts]))
    if not union.size:
        return
    ks = data.draw(st.lists(st.integers(0, union.size - 1), min_size=1, max_size=5))
    found = kth_smallest([np.asarray(p, dtype=np.float64) for p in parts], ks)
    assert found == {k: float(union[k]) for k in ks}


def test_kth_smallest_on_many_values_with_few_probes() -> None:
    rng = np.random.default_rng(4)
    parts = [np.sort(rng.gamma(2.0, 3.0, n).round(2)) for n in (90_000, 0, 7, 300_000, 1)]
    union = np.sort(np.concatenate(parts))
    ks = [0, 1, union.size // 2, union.size * 9 // 10, union.size - 1]
    assert kth_smallest(parts, ks) == {k: float(union[k]) for k in ks}


def test_quantiles_under_ignore_use_evaluated_points_only() -> None:
    # 7 valid errors 0..6 and 3 holes: ignore → N = 7, a50 = [3] = 3, a90 = [6] = 6;
    # thesis → holes have e = 100: N = 10, a50 = [5] = 5, a90 = [9] = 100
    gt = np.full((1, 10), 100.0, np.float32)
    est = np.array([[100, 101, 102, 103, 104, 105, 106, NAN, 0, -1]], np.float32)
    ignore = Evaluator(criteria=("all",), missing="ignore").score(gt, est)["all"]
    thesis = Evaluator(criteria=("all",), missing="thesis").score(gt, est)["all"]
    assert (ignore["a50"], ignore["a90"]) == (3.0, 6.0)
    assert (thesis["a50"], thesis["a90"]) == (5.0, 100.0)


# ------------------------------------------------------------------------------------ combine


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


# ----------------------------------------------------------------------------------- criteria


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


# ------------------------------------------------------------------------------------- cache


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


# ------------------------------------------------------------------------------------ errors


def test_shape_mismatch_errors() -> None:
    evaluator = Evaluator(criteria=("all", "visibility", "roi"))
    gt = np.ones((3, 4), np.float32)
    cases = [
        lambda: evaluator.score(gt, np.ones((4, 3), np.float32), roi=np.ones((3, 4))),
        lambda: evaluator.score(
            gt, gt, masks={"nonocc": np.ones((3, 5), bool)}, roi=np.ones((3, 4))
        ),
        lambda: evaluator.score(gt, gt, roi=np.ones((2, 4))),
        lambda: evaluator.score(gt, gt, gt_right=np.ones((3, 3), np.float32), roi=np.ones((3, 4))),
    ]
    for case in cases:
        with pytest.raises(ShapeMismatchError) as error:
            case()
        one_line(error)


@pytest.mark.parametrize(
    "gt",
    [np.zeros((3, 3)), np.full((2, 2), np.nan), np.full((2, 2), -1.0), np.full((2, 2), np.inf)],
)
def test_all_invalid_gt(gt: np.ndarray) -> None:
    with pytest.raises(EmptyGroundTruthError) as error:
        Evaluator().score(gt, np.ones_like(gt))
    one_line(error)


def test_all_mask_that_leaves_nothing() -> None:
    gt = np.ones((2, 2), np.float32)
    with pytest.raises(EmptyGroundTruthError) as error:
        Evaluator().score(gt, gt, masks={"all": np.zeros((2, 2), bool)})
    assert "'all' mask" in one_line(error)


@pytest.mark.parametrize(
    ("gt", "est"),
    [
        (np.ones((2, 2, 3)), np.ones((2, 2))),
        (np.ones((2, 2)), np.ones((2, 2, 1))),
        (np.ones(4), np.ones(4)),
        (np.ones((2, 2), complex), np.ones((2, 2))),
        (np.ones((2, 2)), np.ones((2, 2), complex)),
        (np.array([["a", "b"]]), np.ones((1, 2))),
        ([[1.0, 2.0], [3.0]], np.ones((2, 2))),
    ],
)
def test_input_errors(gt: object, est: object) -> None:
    with pytest.raises(InputError) as error:
        Evaluator(criteria=("all",)).score(gt, est)  # type: ignore[arg-type]
    one_line(error)


@pytest.mark.parametrize(
    "make",
    [
        lambda: Evaluator(criteria=("all", "nope")),
        lambda: Evaluator(criteria=()),
        lambda: Evaluator(missing="skip"),
        lambda: Evaluator(measures=("bmp", "epe")),
        lambda: Evaluator(measures=()),
        lambda: Evaluator(delta=0),
        lambda: Evaluator(mu=-1),
        lambda: Evaluator().score(np.ones((2, 2)), np.ones((2, 2)), masks={"occ": np.ones((2, 2))}),
        lambda: Evaluator(criteria=("roi",)).score(np.ones((2, 2)), np.ones((2, 2))),
        lambda: Evaluator(criteria=("depth",), depth_ranges=[(0, 10)]).score(
            np.ones((2, 2)), np.ones((2, 2))
        ),
        lambda: Evaluator(criteria=("depth",), depth_ranges=[(0, 10), (20, math.inf)]).score(
            np.ones((2, 2)), np.ones((2, 2)), Camera(f=1.0, baseline=1.0)
        ),
        lambda: Evaluator(criteria=("roi",), roi_names={1: "a", 2: "a"}).score(
            np.ones((2, 2)), np.ones((2, 2)), roi=np.ones((2, 2))
        ),
    ],
)
def test_configuration_errors(make) -> None:
    with pytest.raises(ConfigurationError) as error:
        make()
    one_line(error)


def test_unknown_names_are_named_in_the_message() -> None:
    for make, name in (
        (lambda: Evaluator(criteria=("bogus",)), "bogus"),
        (lambda: Evaluator(missing="bogus"), "bogus"),
        (lambda: Evaluator(measures=("bogus",)), "bogus"),
    ):
        with pytest.raises(ConfigurationError) as error:
            make()
        assert name in one_line(error)


def test_scores_unknown_criterion_is_a_key_error() -> None:
    scores = Evaluator(criteria=("all",)).score(GT_HAND, EST_HAND)
    assert "interior" not in scores
    assert scores.get("interior") is None
    with pytest.raises(KeyError):
        scores["interior"]


# ----------------------------------------------------------------------- property-based tests

GT_VALUES = st.one_of(
    st.floats(0.25, 64.0, width=32),
    st.sampled_from([1.0, 4.0, 4.0, 12.5, 30.0, 30.5]),
    st.sampled_from([0.0, NAN, INF, -2.0]),
)
OFFSETS = st.one_of(
    st.sampled_from([0.0, 0.0, 1.0, -1.0, 0.5, 3.5, -20.0]), st.floats(-6.0, 6.0, width=32)
)
CAMERAS = st.one_of(
    st.none(),
    st.builds(
        Camera,
        f=st.floats(50, 1500),
        baseline=st.floats(0.05, 1.0),
        doffs=st.sampled_from([0.0, 0.0, 12.5, 60.0]),
    ),
)


@st.composite
def frames(draw: st.DrawFn) -> dict[str, object]:
    """A small GT with random invalid points, an estimate with every kind of missing value."""
    height = draw(st.integers(1, 9))
    width = draw(st.integers(2, 12))
    shape = (height, width)
    gt = draw(hnp.arrays(np.float32, shape, elements=GT_VALUES))
    gt[0, 0] = 3.0  # at least one valid point
    offsets = draw(hnp.arrays(np.float32, shape, elements=OFFSETS))
    kinds = draw(hnp.arrays(np.int8, shape, elements=st.integers(0, 6)))
    with np.errstate(invalid="ignore"):
        base = np.where(np.isfinite(gt) & (gt > 0), gt, np.float32(10.0))
        est = (base + offsets).astype(np.float32)
    specials = {3: NAN, 4: 0.0, 5: -1.0, 6: 90.0}  # 90: outside est_range when one is given
    for kind, value in specials.items():
        est[kinds == kind] = value
    roi = draw(hnp.arrays(np.int8, shape, elements=st.integers(0, 3)))
    use_masks = draw(st.booleans())
    masks = None
    if use_masks:
        masks = {
            name: draw(hnp.arrays(np.bool_, shape, elements=st.booleans()))
            for name in ("nonocc", "disc")
        }
        if draw(st.booleans()):
            masks["all"] = draw(hnp.arrays(np.bool_, shape, elements=st.booleans()))
            masks["all"][0, 0] = True
    return {
        "gt": gt,
        "est": est,
        "roi": roi,
        "masks": masks,
        "camera": draw(CAMERAS),
        "est_range": draw(st.sampled_from([None, (0.5, 64.0), (2.0, 40.0)])),
        "delta": draw(st.sampled_from([1.0, 0.5, 2.0])),
    }


def independent_criteria(frame: dict, partition) -> dict[str, np.ndarray]:
    """Criterion masks built here, except the 3-means (checked by its own property test)."""
    gt = frame["gt"]
    masks = frame["masks"] or {}
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(gt) & (gt > 0)
    if "all" in masks:
        valid &= masks["all"]
    if "nonocc" in masks:
        occluded = valid & ~masks["nonocc"]
        near = masks["disc"]
    else:
        occluded = zbuffer_occlusion(gt, valid)
        near = near_jumps(gt, valid)
    boundary = valid & near & ~occluded
    interior = valid & ~near & ~occluded
    roi = frame["roi"]
    return {
        "all": valid,
        "occluded": occluded,
        "boundary": boundary,
        "interior": interior,
        "road": valid & (roi == 1),
        "car": valid & (roi == 2),
        "unlabelled": valid & (roi != 1) & (roi != 2),
        "nonocc": boundary | interior,
        "disc": boundary,
        **{name: partition.mask(name) for name in ("near", "mid", "far")},
    }


CRITERIA = ("all", "visibility", "depth", "roi", "legacy")
PROPERTY = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@PROPERTY
@given(frame=frames())
def test_partitions_are_disjoint_and_cover_the_valid_points(frame: dict) -> None:
    evaluator = Evaluator(criteria=CRITERIA, roi_names={1: "road", 2: "car"})
    reference = evaluator.reference(
        frame["gt"], frame["camera"], masks=frame["masks"], roi=frame["roi"]
    )
    partition = reference.partition
    expected = independent_criteria(frame, partition)
    valid = expected["all"]
    counts = partition.counts()
    sets = {
        "all": ("all",),
        "visibility": ("occluded", "boundary", "interior"),
        "depth": ("near", "mid", "far"),
        "roi": ("road", "car", "unlabelled"),
    }
    for members in sets.values():
        stack = np.array([partition.mask(name) for name in members], dtype=np.int64)
        np.testing.assert_array_equal(stack.sum(axis=0), valid.astype(np.int64))
        for name in members:
            assert counts[name] == int(partition.mask(name).sum())
        assert sum(counts[name] for name in members) == int(valid.sum())
    for name, mask in expected.items():
        np.testing.assert_array_equal(partition.mask(name), mask, err_msg=name)
    assert set(partition.overlapping) == {"nonocc", "disc"}


@PROPERTY
@given(frame=frames(), policy=st.sampled_from(POLICIES))
def test_scores_equal_numpy_recomputation(frame: dict, policy: str) -> None:
    evaluator = Evaluator(
        criteria=CRITERIA, missing=policy, delta=frame["delta"], roi_names={1: "road", 2: "car"}
    )
    kwargs = {"masks": frame["masks"], "roi": frame["roi"]}
    scores = evaluator.score(
        frame["gt"], frame["est"], frame["camera"], est_range=frame["est_range"], **kwargs
    )
    partition = evaluator.reference(frame["gt"], frame["camera"], **kwargs).partition
    expected = numpy_measures(
        frame["gt"],
        frame["est"],
        independent_criteria(frame, partition),
        policy,
        camera=frame["camera"],
        est_range=frame["est_range"],
        delta=frame["delta"],
    )
    assert scores.relative == (frame["camera"] is None)
    assert_matches(scores, expected)


def check_three_means(gt: np.ndarray, partition) -> None:
    """Lloyd fixed point: each value is nearest its own centroid, centroids are the means."""
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(gt) & (gt > 0)
    values = gt.astype(np.float64)
    clusters = [values[partition.mask(name)] for name in ("far", "mid", "near")]
    assert sum(c.size for c in clusters) == int(valid.sum())
    occupied = [c for c in clusters if c.size]
    centroids = np.array([c.mean() for c in occupied])
    # equal within float32 resolution counts as a tie (a value on a threshold)
    tolerance = 4 * np.finfo(np.float32).eps * float(np.abs(values[valid]).max())
    for own, cluster in enumerate(occupied):
        distances = np.abs(cluster[:, None] - centroids[None, :])
        assert (distances[:, own] <= distances.min(axis=1) + tolerance).all()
    # clusters are ordered intervals: far < mid < near
    for lower, upper in itertools.pairwise(occupied):
        assert lower.max() < upper.min()


@settings(max_examples=150, deadline=None)
@given(
    gt=hnp.arrays(
        np.float32,
        st.tuples(st.integers(1, 6), st.integers(1, 12)),
        elements=st.one_of(
            st.floats(0.5, 200.0, width=32), st.sampled_from([0.0, NAN, 1.0, 2.0, 3.0, 4.0, 7.0])
        ),
    )
)
def test_three_means_is_a_deterministic_fixed_point(gt: np.ndarray) -> None:
    gt[0, 0] = 5.0
    partition = Evaluator(criteria=("depth",)).reference(gt).partition
    check_three_means(gt, partition)
    again = Evaluator(criteria=("depth",)).reference(gt.copy()).partition
    for name in ("near", "mid", "far"):
        np.testing.assert_array_equal(partition.mask(name), again.mask(name))
