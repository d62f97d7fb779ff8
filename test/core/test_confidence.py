"""Confidence measures checked against sort-based numpy written from the definitions.

The re-computation here ranks each pixel by its confidence level (a stable sort), gives each
pixel of a tie group the group's mean error (the expectation over the group's orders), and
integrates ``ε(δ) = S(δ)/(δN)`` pixel by pixel, ``S`` linear between pixels: no levels, no
binning, no cells. The oracle ranks by the true error (binned as documented for continuous
measures; a bad share's oracle is the formula). Real scenes: OpenCV's WLS filter confidences
(opencv-contrib, installed beside the suite by ``.ci/run``; see ``wls_outputs``).
"""

from __future__ import annotations

import itertools
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.confidence import (
    PRESETS,
    ConfidenceScorer,
    ConfidenceSums,
    Curve,
    grading,
    optimal_auc,
    parse_preset,
    sparsification,
)
from dispeval_ros.core.evaluator import Evaluator, Reference
from dispeval_ros.core.kernels.confidence import ERROR_BINS, error_bins
from dispeval_ros.errors import ConfigurationError, InputError, ShapeMismatchError
from dispeval_ros.io import load_scene

CRITERIA = ("all", "visibility", "depth")
THRESHOLDS = (0.5, 2.0, 4.0)


def numpy_auc(rank: np.ndarray, error: np.ndarray) -> float:
    """∫₀¹ ε(δ) dδ ranking by ``rank`` (ascending, ties averaged), pixel by pixel."""
    if rank.size == 0:
        return math.nan
    order = np.argsort(rank, kind="stable")
    rank, error = rank[order], np.asarray(error, dtype=np.float64)[order]
    _, first, size = np.unique(rank, return_index=True, return_counts=True)
    error = np.repeat(np.add.reduceat(error, first) / size, size)
    n = error.size
    before = np.concatenate([[0.0], np.cumsum(error)[:-1]])
    k = np.arange(1, n + 1, dtype=np.float64)
    # on [(k−1)/n, k/n]: S(δ) = before − (k−1)·e + δ·n·e, so ∫ S/(δn) = (before − (k−1)e)/n·ln(k/(k−1)) + e/n
    log_term = np.zeros(n)
    log_term[1:] = np.log(k[1:] / (k[1:] - 1))
    return float(np.sum((before - (k - 1) * error) / n * log_term + error / n))


def permutation_auc(groups: list[list[float]]) -> float:
    """The mean AUC over every order of each tie group's points (tiny cases only)."""
    areas = []
    for orders in itertools.product(*(itertools.permutations(g) for g in groups)):
        errors = np.array([e for group in orders for e in group])
        areas.append(numpy_auc(np.arange(errors.size), errors))
    return float(np.mean(areas))


def expected_pixels(
    reference: Reference, evaluator: Evaluator, est: np.ndarray, criterion: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(error, depth error, valid) at a criterion's points, straight from the maps."""
    mask = reference.partition.mask(criterion)
    d = reference.gt[mask].astype(np.float64)
    raw = est[mask].astype(np.float64)
    valid = np.isfinite(raw) & (raw > 0)
    scored = np.where(valid, raw, 0.0)  # thesis: a missing estimate is scored as 0
    error = np.abs(scored - d)
    doffs = reference.depth_offset - evaluator.mu
    inverse_d = np.maximum(d + doffs, evaluator.mu)
    inverse_e = np.maximum(scored + doffs, evaluator.mu)
    depth = reference.fb * np.abs(inverse_d - inverse_e) / (inverse_d * inverse_e)
    return error, depth, valid


def numpy_curves(
    reference: Reference,
    evaluator: Evaluator,
    est: np.ndarray,
    confidence: np.ndarray,
    preset: str,
    criterion: str,
) -> dict[str, tuple[float, float]]:
    """measure → (AUC, optimal AUC) from the definitions (``ignore`` or ``thesis`` policy)."""
    mask = reference.partition.mask(criterion)
    error, depth, valid = expected_pixels(reference, evaluator, est, criterion)
    levels = grading(parse_preset(preset), confidence.dtype)
    rank = levels.level(confidence[mask])
    rank = np.where(valid, rank, levels.levels)  # no estimate: ranked last
    if evaluator.missing == "ignore":
        error, depth, rank, d = error[valid], depth[valid], rank[valid], reference.gt[mask][valid]
    else:
        d = reference.gt[mask]
    result = {}
    for t in THRESHOLDS:
        bad = (error > t).astype(np.float64)
        result[f"bad_{t:g}"] = (
            100 * numpy_auc(rank, bad),
            100 * optimal_auc(bad.mean()) if bad.size else math.nan,
        )
    d1 = ((error > 3.0) & (error > 0.05 * d)).astype(np.float64)
    result["d1"] = (
        100 * numpy_auc(rank, d1),
        100 * optimal_auc(d1.mean()) if d1.size else math.nan,
    )
    result["mae"] = (numpy_auc(rank, error), numpy_auc(error_bins(error), error))
    result["mae_z"] = (numpy_auc(rank, depth), numpy_auc(error_bins(depth), depth))
    return result


def assert_curves(
    sums: ConfidenceSums, expected: dict[str, tuple[float, float]], criterion: str
) -> None:
    for measure, (auc, auc_opt) in expected.items():
        curve = sums.curve(criterion, measure)
        close = {"rel": 1e-9, "abs": 1e-12, "nan_ok": True}
        assert curve.auc == pytest.approx(auc, **close), (criterion, measure)
        assert curve.auc_opt == pytest.approx(auc_opt, **close), (criterion, measure)
        assert curve.ause == pytest.approx(auc - auc_opt, rel=1e-8, abs=1e-10, nan_ok=True)


def synthetic_frame(seed: int, shape: tuple[int, int] = (120, 160)) -> tuple[np.ndarray, ...]:
    """A smooth dense GT with occlusion-free jumps, a noisy estimate with holes, 8-bit ties."""
    rng = np.random.default_rng(seed)
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    gt = (20 + 10 * np.sin(cols / 17.0) + rows / 12.0).astype(np.float32)
    gt[rng.random(shape) < 0.1] = 0.0  # no GT
    error = rng.standard_t(3, shape) * 1.2
    est = (gt + error).astype(np.float32)
    est[rng.random(shape) < 0.08] = 0.0  # no estimate
    # a few levels only: many ties, informative (bigger errors less confident) but imperfect
    confidence = np.clip(200 - 30 * np.abs(error) + rng.normal(0, 25, shape), 0, 255)
    confidence = (np.round(confidence / 40) * 40).astype(np.uint8)
    return gt, est, confidence


def scored(sums: ConfidenceSums) -> list[str]:
    """The criteria with points (a synthetic frame has no occlusions)."""
    return [c for c, n in zip(sums.criteria, sums.points, strict=True) if n > 0]


def camera_for(shape: tuple[int, int]) -> Camera:
    """A KITTI-like camera (the depth error needs one)."""
    return Camera(f=720.0, baseline=0.54)


# -- hand-worked cases and the definitions ------------------------------------------------


def test_random_confidence_gives_the_mean_and_a_perfect_one_the_optimum() -> None:
    # two levels of two points, one bad in each: ε(δ) = ½ throughout, AUC = ½
    density, error, area = sparsification(np.array([2, 2]), np.array([1.0, 1.0]))
    assert area == pytest.approx(0.5)
    assert density.tolist() == [0.5, 1.0]
    assert error.tolist() == [0.5, 0.5]
    # bad points last: zero up to 1 − ε, then (δ − 1 + ε)/δ: ε + (1 − ε)·ln(1 − ε)
    for share in (0.1, 0.25, 0.5, 0.9):
        n = 1000
        bad = round(share * n)
        _, _, area = sparsification(np.array([n - bad, bad]), np.array([0.0, bad]))
        assert area == pytest.approx(optimal_auc(bad / n), rel=1e-12)
    assert optimal_auc(0.0) == 0.0
    assert optimal_auc(1.0) == 1.0


def test_ties_are_the_mean_over_every_order_of_the_tied_points() -> None:
    groups = [[0.0, 3.0, 1.0], [2.0, 0.5], [4.0, 0.0, 1.0]]
    counts = np.array([len(g) for g in groups])
    sums = np.array([sum(g) for g in groups])
    assert sparsification(counts, sums)[2] == pytest.approx(permutation_auc(groups), rel=1e-12)


def test_matches_numpy_on_synthetic_ties_every_criterion_and_policy() -> None:
    gt, est, confidence = synthetic_frame(1)
    for missing in ("ignore", "thesis"):
        evaluator = Evaluator(criteria=CRITERIA, missing=missing)
        reference = evaluator.reference(gt, camera_for(gt.shape))
        sums = ConfidenceScorer(evaluator, parse_preset("wls"), THRESHOLDS).score(
            reference, est, confidence
        )
        for criterion in sums.criteria:
            expected = numpy_curves(reference, evaluator, est, confidence, "wls", criterion)
            assert_curves(sums, expected, criterion)


def test_the_curve_ends_at_the_frame_measures() -> None:
    gt, est, confidence = synthetic_frame(2)
    evaluator = Evaluator(criteria=CRITERIA, measures=("bad_2", "d1", "mae", "density"))
    reference = evaluator.reference(gt, camera_for(gt.shape))
    sums = ConfidenceScorer(evaluator, parse_preset("wls"), (2.0,)).score(
        reference, est, confidence
    )
    scores = evaluator.score(reference, est)
    for criterion in scored(sums):
        for measure in ("bad_2", "d1", "mae"):
            end = sums.curve(criterion, measure).error[-1]
            assert end == pytest.approx(scores[criterion][measure], rel=1e-9)
        summary = sums.summary()[criterion]
        assert summary["density"] == pytest.approx(scores[criterion]["density"], rel=1e-12)


def test_a_perfect_confidence_reaches_the_optimal_auc() -> None:
    gt, est, _ = synthetic_frame(3)
    evaluator = Evaluator(criteria=CRITERIA, missing="ignore")
    reference = evaluator.reference(gt, camera_for(gt.shape))
    error = np.abs(est.astype(np.float64) - gt)
    for threshold in THRESHOLDS:
        confidence = np.where(error <= threshold, 255, 0).astype(np.uint8)  # the true order
        sums = ConfidenceScorer(evaluator, PRESETS["wls"], THRESHOLDS).score(
            reference, est, confidence
        )
        for criterion in scored(sums):
            curve = sums.curve(criterion, f"bad_{threshold:g}")
            assert curve.auc == pytest.approx(curve.auc_opt, rel=1e-12, abs=1e-12)
            assert curve.ratio == pytest.approx(1.0) or curve.auc_opt == 0
    # a confidence in the true error's order (lower is better, one level per error bin): AUSE 0
    confidence = error_bins(error).astype(np.float32)
    preset = parse_preset(f"lower:0:{ERROR_BINS}")
    sums = ConfidenceScorer(evaluator, preset).score(reference, est, confidence)
    assert grading(preset, np.dtype(np.float32)).levels >= 256
    curve = sums.curve("all", "mae")
    assert curve.ause == pytest.approx(0.0, abs=0.02 * curve.auc_opt)


def test_pooled_over_a_sequence_equals_all_pixels_at_once() -> None:
    frames = [synthetic_frame(seed) for seed in (4, 5, 6)]
    evaluator = Evaluator(criteria=CRITERIA, missing="ignore")
    scorer = ConfidenceScorer(evaluator, parse_preset("wls"), THRESHOLDS)
    references = [evaluator.reference(gt, camera_for(gt.shape)) for gt, _, _ in frames]
    parts = [
        scorer.score(reference, est, confidence)
        for reference, (_, est, confidence) in zip(references, frames, strict=True)
    ]
    pooled = ConfidenceSums.pooled(parts)
    level = grading(PRESETS["wls"], np.dtype(np.uint8))
    for criterion in scored(pooled):
        error, rank = [], []
        for reference, (_, est, confidence) in zip(references, frames, strict=True):
            e, _, valid = expected_pixels(reference, evaluator, est, criterion)
            error.append(e[valid])
            rank.append(level.level(confidence[reference.partition.mask(criterion)])[valid])
        errors, ranks = np.concatenate(error), np.concatenate(rank)
        bad = (errors > 2.0).astype(np.float64)
        curve = pooled.curve(criterion, "bad_2")
        assert curve.auc == pytest.approx(100 * numpy_auc(ranks, bad), rel=1e-9)
        assert curve.auc_opt == pytest.approx(100 * optimal_auc(bad.mean()), rel=1e-12)
        mae = pooled.curve(criterion, "mae")
        assert mae.auc == pytest.approx(numpy_auc(ranks, errors), rel=1e-9)
        assert mae.auc_opt == pytest.approx(numpy_auc(error_bins(errors), errors), rel=1e-9)
        # the pooled curve's points: each level's cumulative mean over all frames' pixels
        for density, value in zip(curve.density, curve.error, strict=True):
            kept = np.argsort(ranks, kind="stable")[: round(density * ranks.size)]
            assert value == pytest.approx(100 * bad[kept].mean(), rel=1e-9)


def test_presets_rank_each_convention_most_confident_first() -> None:
    def levels(preset: str, values: list[float], dtype: type) -> list[int]:
        array = np.array(values, dtype=dtype)
        return grading(parse_preset(preset), array.dtype).level(array).tolist()

    assert levels("zed", [0.0, 50.0, 100.0], np.float32) == [0, 128, 255]
    assert levels("realsense", [15, 14, 0], np.uint8) == [0, 1, 15]
    assert grading(PRESETS["realsense"], np.dtype(np.uint8)).levels == 16
    assert levels("vpi", [65535, 65280, 0], np.uint16) == [0, 0, 255]
    assert levels("wls", [255.0, 254.0, 0.0], np.float32) == [0, 1, 255]
    assert levels("higher", [255, 0], np.uint8) == [0, 255]
    assert levels("lower:0:1", [0.0, 1.0, math.nan], np.float32) == [0, 255, 256]
    # every 8-bit value its own level: the look-up table the kernel reads agrees
    wls = grading(PRESETS["wls"], np.dtype(np.uint8))
    assert len(set((wls.lut & 0xFFFF).tolist())) == 256


# -- bad input -----------------------------------------------------------------------------


def test_bad_input_is_one_clear_line() -> None:
    gt, est, confidence = synthetic_frame(7)
    evaluator = Evaluator(criteria=("all",))
    reference = evaluator.reference(gt)
    scorer = ConfidenceScorer(evaluator, PRESETS["wls"])
    with pytest.raises(ShapeMismatchError, match="the confidence is 159×120"):
        scorer.score(reference, est, confidence[:, :-1])
    with pytest.raises(ConfigurationError, match="unknown confidence preset 'zedd'"):
        parse_preset("zedd")
    with pytest.raises(ConfigurationError, match="LOW must be below HIGH"):
        parse_preset("higher:1:0")
    with pytest.raises(InputError, match="no finite value"):
        scorer.score(reference, est, np.full(gt.shape, np.nan, dtype=np.float32))
    with pytest.raises(ConfigurationError, match="higher:LOW:HIGH"):
        ConfidenceScorer(evaluator, PRESETS["higher"]).score(
            reference, est, confidence.astype(np.float32)
        )


def test_nan_and_out_of_range_confidences_are_ranked_last_and_counted() -> None:
    gt, est, confidence = synthetic_frame(8)
    evaluator = Evaluator(criteria=("all",), missing="ignore")
    reference = evaluator.reference(gt)
    rated = confidence.astype(np.float32)
    rated[:10] = np.nan
    rated[10:12] = 300.0  # above the WLS range: clamped to its best end
    sums = ConfidenceScorer(evaluator, PRESETS["wls"]).score(reference, est, rated)
    mask = reference.partition.mask("all")
    valid = est > 0
    summary = sums.summary(["mae"])["all"]
    assert summary["n_unrated"] == np.count_nonzero(mask[:10] & valid[:10])
    assert summary["n_clamped"] == np.count_nonzero(mask[10:12])
    expected = numpy_curves(reference, evaluator, est, rated, "wls", "all")
    assert_curves(sums, {"mae": expected["mae"]}, "all")


# -- real scenes, OpenCV WLS confidences ---------------------------------------------------

WLS_SCRIPT = """
import sys, cv2, numpy as np
left, right, out, disparities = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
L, R = cv2.imread(left, cv2.IMREAD_GRAYSCALE), cv2.imread(right, cv2.IMREAD_GRAYSCALE)
matcher = cv2.StereoSGBM_create(0, disparities, 5, 8 * 25, 32 * 25, 1, 63, 10, 100, 2)
wls = cv2.ximgproc.createDisparityWLSFilter(matcher)
right_matcher = cv2.ximgproc.createRightMatcher(matcher)
filtered = wls.filter(matcher.compute(L, R), L, disparity_map_right=right_matcher.compute(R, L))
np.savez(out, disparity=filtered.astype(np.float32) / 16.0, confidence=wls.getConfidenceMap())
"""


def contrib_python_path() -> str:
    """Where opencv-contrib lies (``DISPEVAL_OPENCV_CONTRIB``), or skip / fail under CI."""
    configured = os.environ.get("DISPEVAL_OPENCV_CONTRIB", "")
    if configured and (Path(configured) / "cv2").is_dir():
        return configured
    reason = (
        "OpenCV's WLS filter (opencv-contrib) not found: install it apart with `pip install "
        "--target DIR -r test/requirements-contrib.txt` and set DISPEVAL_OPENCV_CONTRIB=DIR"
    )
    if os.environ.get("DISPEVAL_REQUIRE_DATA") == "1":
        pytest.fail(f"DISPEVAL_REQUIRE_DATA=1 but {reason}")
    pytest.skip(reason)


@pytest.mark.parametrize(
    ("scene", "disparities"),
    [("kitti-2015/000005_10", 128), ("middlebury-2001-2003/teddy", 64)],
)
def test_real_scenes_with_wls_confidences_match_numpy(
    shared_data: Path, tmp_path: Path, scene: str, disparities: int
) -> None:
    loaded = load_scene(shared_data / scene)
    out = tmp_path / "wls.npz"
    subprocess.run(
        [sys.executable, "-c", WLS_SCRIPT, str(loaded.left), str(loaded.right), str(out),
         str(disparities)],
        check=True,
        env={**os.environ, "PYTHONPATH": contrib_python_path()},
    )  # fmt: skip
    wls = np.load(out)
    est, confidence = wls["disparity"], wls["confidence"]
    assert confidence.dtype == np.float32
    assert 0 <= confidence.min() < confidence.max() <= 255
    for missing in ("ignore", "thesis"):
        evaluator = Evaluator(criteria=CRITERIA, missing=missing)
        reference = evaluator.reference(loaded.gt, loaded.camera, masks=loaded.masks)
        sums = ConfidenceScorer(evaluator, parse_preset("wls"), THRESHOLDS).score(
            reference, est, confidence
        )
        for criterion in sums.criteria:
            expected = numpy_curves(reference, evaluator, est, confidence, "wls", criterion)
            if loaded.camera is None:
                expected.pop("mae_z")
            assert_curves(sums, expected, criterion)
        # WLS's confidence is informative: better than random (ratio to the optimum < mean's)
        curve = sums.curve("all", "bad_2")
        assert curve.auc < curve.error[-1]


def test_the_drawn_curve_is_exact_between_group_ends() -> None:
    # ranked groups with ties; at k kept points the expected error is the numpy per-pixel one
    groups = [[0.0, 1.0, 0.0, 1.0], [1.0, 1.0, 0.0], [1.0, 1.0, 1.0, 0.0, 1.0]]
    counts = np.array([len(g) for g in groups])
    density, error, area = sparsification(counts, np.array([sum(g) for g in groups]))
    drawn = Curve(density, error, area, 0.0, density, error)
    errors = np.concatenate([np.full(len(g), np.mean(g)) for g in groups])  # ties: group mean
    kept = np.arange(1, errors.size + 1)
    expected = np.cumsum(errors) / kept
    assert drawn.at(kept / errors.size) == pytest.approx(expected, rel=1e-12)
    # curved, not straight, inside a group: the midpoint is not the chord's midpoint
    middle = drawn.at(np.array([(density[0] + density[1]) / 2]))[0]
    assert middle != pytest.approx((error[0] + error[1]) / 2)
