"""Temporal measures with ground truth (issue 24, item 1): TEPE of consecutive frames.

Every value is checked against an independent plain-numpy recomputation written here from the
definition (docs/method.md, "Temporal measures"): ``e = |(E_t − E_t+1) − (D_t − D_t+1)|`` at
the same pixel, over the pixels with valid GT in both frames, each frame's estimate scored under
the missing-estimate policy as :func:`reference.scored_estimate` scores it; ``tepe`` the mean
of ``e``, ``tepe_r`` the mean of ``e / (|D_t − D_t+1| + 10⁻³)``, ``tepe_bad_X`` the share of
``e > X`` in %. Only the criteria's pixel sets are taken from the library (its partition is
tested elsewhere).
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest
from reference import POLICIES, scored_estimate

from dispeval_ros.core import registry
from dispeval_ros.core.evaluator import Evaluator, Reference
from dispeval_ros.core.kernels import temporal as kernel
from dispeval_ros.core.temporal import (
    PRESETS,
    PairScores,
    TemporalScorer,
    frame_weighted_mean,
)
from dispeval_ros.errors import ConfigurationError, ShapeMismatchError
from dispeval_ros.testbed import default_methods, make_driving_sequence

CRITERIA = ("all", "visibility", "depth")
MEASURES = ("tepe", "tepe_r", "tepe_bmp", "tepe_bad_0.5", "tepe_bad_3")
EPSILON = 1e-3  # px: the relative TEPE's denominator offset, as published


# ------------------------------------------------------------------ independent reference


def _valid(gt: np.ndarray) -> np.ndarray:
    return np.isfinite(gt) & (gt > 0)


def pair_errors(
    gt: np.ndarray, gt_next: np.ndarray, est: np.ndarray, est_next: np.ndarray, policy: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(temporal error, |ΔD|, scored) per pixel; errors in float64 from the float32 maps."""
    value, takes_part = scored_estimate(est, policy)
    value_next, takes_part_next = scored_estimate(est_next, policy)
    both = _valid(gt) & _valid(gt_next)
    with np.errstate(invalid="ignore"):
        change = np.where(both, gt.astype(np.float64) - gt_next.astype(np.float64), 0.0)
    error = np.abs((value - value_next) - change)
    return error, np.abs(change), both & takes_part & takes_part_next


def measures_of(error: np.ndarray, change: np.ndarray, nonzero_only: bool = False) -> dict:
    """The pair measures of a set of pixels' temporal errors (DynamicStereo's denominator:
    the non-zero errors, an all-zero set scoring 0)."""
    count = np.count_nonzero(error) if nonzero_only else error.size
    if count == 0:
        zero = 0.0 if nonzero_only and error.size else math.nan
        return dict.fromkeys(MEASURES, zero)
    return {
        "tepe": error.sum() / count,
        "tepe_r": (error / (change + EPSILON)).sum() / count,
        "tepe_bmp": 100.0 * np.count_nonzero(error > 1.0) / count,
        "tepe_bad_0.5": 100.0 * np.count_nonzero(error > 0.5) / count,
        "tepe_bad_3": 100.0 * np.count_nonzero(error > 3.0) / count,
    }


def expected(reference: Reference, gt_next, est, est_next, policy: str) -> dict:
    error, change, scored = pair_errors(reference.gt, gt_next, est, est_next, policy)
    result = {}
    for criterion in reference.partition.criteria:
        pixels = reference.partition.mask(criterion) & scored
        result[criterion] = measures_of(error[pixels], change[pixels])
        result[criterion]["n_pair"] = int(
            (reference.partition.mask(criterion) & _valid(gt_next)).sum()
        )
    return result


def assert_scores(scores: PairScores, want: dict) -> None:
    for criterion, values in want.items():
        got = scores[criterion]
        assert got["n_pair"] == values["n_pair"], criterion
        for name in MEASURES:
            assert got[name] == pytest.approx(values[name], rel=1e-9, abs=1e-12, nan_ok=True), (
                criterion,
                name,
            )


# ------------------------------------------------------------------ scenes


def with_holes(gt: np.ndarray, index: int) -> np.ndarray:
    """The GT with a band of no ground truth that moves from frame to frame (NaN, inf, 0)."""
    gt = gt.copy()
    height, width = gt.shape
    top = (height // 5) * (1 + index % 3)
    left = (width // 7) * (1 + index % 4)
    gt[top : top + height // 8, left : left + width // 6] = (np.nan, np.inf, 0.0)[index % 3]
    return gt


@pytest.fixture(scope="module")
def drive() -> list[tuple[np.ndarray, dict[str, np.ndarray]]]:
    """Four consecutive frames of the synthetic drive: GT (with holes) and OpenCV estimates."""
    frames = []
    methods = [m for m in default_methods(620) if m.name in ("bm_fast", "sgbm")]
    for index, frame in enumerate(make_driving_sequence(n_frames=4, seed=5)):
        estimates = {m.name: m.compute(frame.left, frame.right) for m in methods}
        frames.append((with_holes(frame.gt_left, index), estimates))
    return frames


@pytest.fixture(scope="module")
def sceneflow(shared_data: Path) -> list[tuple[np.ndarray, dict[str, np.ndarray]]]:
    """SceneFlow FlyingThings3D 0006–0008 (dense GT, holes added) and a BM estimate of each."""
    from dispeval_ros.io import list_frames, read_stereo_pair

    folder = shared_data / "sceneflow-flyingthings3d-seq"
    if not folder.is_dir():
        pytest.skip(f"no SceneFlow frames at {folder}")
    [method] = [m for m in default_methods(960) if m.name == "bm_fast"]
    frames = []
    for index, scene in enumerate(list_frames(folder)):
        assert scene.left is not None
        assert scene.right is not None
        left, right = read_stereo_pair(scene.left, scene.right)
        frames.append((with_holes(scene.gt, index), {"bm": method.compute(left, right)}))
    return frames


def _check_sequence(frames, policy: str) -> None:
    evaluator = Evaluator(criteria=CRITERIA, missing=policy)
    scorer = TemporalScorer(evaluator, measures=MEASURES)
    for (gt, estimates), (gt_next, estimates_next) in itertools.pairwise(frames):
        reference = evaluator.reference(gt)
        pair = scorer.pair(reference, gt_next)
        for name, est in estimates.items():
            scores = scorer.score(pair, est, estimates_next[name])
            assert_scores(scores, expected(reference, gt_next, est, estimates_next[name], policy))


@pytest.mark.parametrize("policy", POLICIES)
def test_tepe_equals_the_reference_on_the_synthetic_drive(drive, policy: str) -> None:
    _check_sequence(drive, policy)


@pytest.mark.data
@pytest.mark.parametrize("policy", POLICIES)
def test_tepe_equals_the_reference_on_sceneflow(sceneflow, policy: str) -> None:
    _check_sequence(sceneflow, policy)


def test_policies_differ_where_estimates_are_missing(drive) -> None:
    """The drive's OpenCV estimates have holes: each policy scores them differently."""
    (gt, estimates), (gt_next, estimates_next) = drive[0], drive[1]
    values = {}
    for policy in POLICIES:
        evaluator = Evaluator(criteria=("all",), missing=policy)
        scorer = TemporalScorer(evaluator, measures=MEASURES)
        pair = scorer.pair(evaluator.reference(gt), gt_next)
        values[policy] = scorer.score(pair, estimates["sgbm"], estimates_next["sgbm"])["all"]
    assert len({v["tepe"] for v in values.values()}) == 3


# ------------------------------------------------------------------ the rules


def _exact_grid(gt: np.ndarray) -> np.ndarray:
    """GT on KITTI's 1/256 px grid: ``gt + 1`` is then exact in float32."""
    return (np.round(gt.astype(np.float64) * 256) / 256).astype(np.float32)


@pytest.mark.parametrize("policy", POLICIES)
def test_a_constant_bias_scores_zero(drive, policy: str) -> None:
    evaluator = Evaluator(criteria=CRITERIA, missing=policy)
    for preset in PRESETS:
        scorer = TemporalScorer(evaluator, measures=MEASURES, preset=preset)
        parts = []
        for (raw, _), (raw_next, _) in itertools.pairwise(drive):
            gt, gt_next = _exact_grid(raw), _exact_grid(raw_next)
            biased, biased_next = gt + np.float32(1), gt_next + np.float32(1)
            valid = _valid(gt)
            assert np.all(biased[valid].astype(np.float64) - gt[valid] == 1.0)
            pair = scorer.pair(evaluator.reference(gt), gt_next)
            parts.append(scorer.score(pair, biased, biased_next))
            frame = evaluator.score(pair.reference, biased)["all"]
            assert frame["mae"] == 1.0  # wrong by 1 px: accurate it is not
        for scores in (*parts, PairScores.combine(parts)):
            for criterion in scores.criteria:
                values = scores[criterion]
                if values["n_pair"]:
                    assert all(values[name] == 0.0 for name in MEASURES), (criterion, values)


def test_per_frame_noise_is_not_temporally_consistent(drive) -> None:
    """Noise drawn anew per frame scores E|N_t − N_t+1|; one fixed noise pattern ~0.

    Uniform noise in ±0.4 px keeps every estimate valid (the drive's GT is > 0.43 px):
    E|U_t − U_t+1| = 0.8/3 px, P(|U_t − U_t+1| > 0.5) = (0.3/0.8)².
    """
    rng = np.random.default_rng(24)
    evaluator = Evaluator(criteria=CRITERIA)
    scorer = TemporalScorer(evaluator, measures=MEASURES)
    (gt, _), (gt_next, _) = drive[0], drive[1]
    pair = scorer.pair(evaluator.reference(gt), gt_next)
    noise = rng.uniform(-0.4, 0.4, gt.shape)
    fresh = rng.uniform(-0.4, 0.4, gt.shape)
    noisy = scorer.score(pair, gt + noise, gt_next + fresh)["all"]
    assert noisy["tepe"] == pytest.approx(0.8 / 3, rel=0.01)
    assert noisy["tepe_bad_0.5"] == pytest.approx(100 * (0.3 / 0.8) ** 2, rel=0.02)
    fixed = scorer.score(pair, gt + noise, gt_next + noise)["all"]
    assert fixed["tepe"] < 1e-5  # float32 rounding of the estimates only
    assert fixed["tepe_bad_0.5"] == 0.0


@pytest.mark.parametrize("policy", POLICIES)
def test_pooled_sums_equal_the_measure_over_all_pixels_at_once(drive, policy: str) -> None:
    evaluator = Evaluator(criteria=CRITERIA, missing=policy)
    scorer = TemporalScorer(evaluator, measures=MEASURES)
    parts, errors = [], {}
    for (gt, est), (gt_next, est_next) in itertools.pairwise(drive):
        reference = evaluator.reference(gt)
        parts.append(scorer.score(scorer.pair(reference, gt_next), est["sgbm"], est_next["sgbm"]))
        error, change, scored = pair_errors(gt, gt_next, est["sgbm"], est_next["sgbm"], policy)
        for criterion in reference.partition.criteria:
            pixels = reference.partition.mask(criterion) & scored
            errors.setdefault(criterion, []).append((error[pixels], change[pixels]))
    assert len(parts) == 3
    pooled = PairScores.combine(parts)
    assert pooled.pairs == 3
    for criterion, pieces in errors.items():
        error = np.concatenate([e for e, _ in pieces])
        change = np.concatenate([c for _, c in pieces])
        want = measures_of(error, change)
        for name in MEASURES:
            assert pooled[criterion][name] == pytest.approx(want[name], rel=1e-9, nan_ok=True)
    # not the mean of the pairs' values: a pair with more pixels of a criterion weighs more
    counts = {c: {part[c]["n_pair"] for part in parts} for c in pooled.criteria}
    uneven = [c for c in pooled.criteria if len(counts[c]) > 1]
    assert uneven
    for criterion in uneven:
        mean_of_pairs = np.mean([part[criterion]["tepe"] for part in parts])
        assert pooled[criterion]["tepe"] != pytest.approx(mean_of_pairs, rel=1e-9)


# ------------------------------------------------------------------ DynamicStereo's normalisation


def dynamicstereo_sequence(
    gts: list[np.ndarray], ests: list[np.ndarray], dtype: type = np.float64
) -> dict[str, float]:
    """Their evaluation of one sequence, written from its definition: maps zeroed outside the
    GT mask, ``e`` over the pairs' common mask, sums over the whole sequence divided by the
    number of non-zero ``e``, bad-X as shares of that number (%). Their code computes in
    float32 (``dtype``); the library in float64, where the differences are exact."""
    masks = [_valid(gt).astype(dtype) for gt in gts]
    y = [np.where(m > 0, gt, 0).astype(dtype) for m, gt in zip(masks, gts, strict=True)]
    x = [np.asarray(est, dtype) * m for m, est in zip(masks, ests, strict=True)]
    errors = [
        masks[t] * masks[t + 1] * np.abs((x[t] - x[t + 1]) - (y[t] - y[t + 1]))
        for t in range(len(gts) - 1)
    ]
    error = np.concatenate([e.ravel() for e in errors])
    nonzero = max(np.count_nonzero(error), 1e-5)
    out = {"tepe": error.sum() / nonzero}
    for threshold in (0.5, 1, 2, 3):
        out[f"tepe_bad_{threshold:g}"] = 100.0 * np.count_nonzero(error > threshold) / nonzero
    return out


def test_the_dynamicstereo_preset_reproduces_its_evaluation(drive) -> None:
    """Two sequences (of 4 and 3 frames), dense estimates: per-sequence values, then the
    frame-weighted mean over sequences, as their aggregate computes it."""
    rng = np.random.default_rng(7)
    gts = [gt for gt, _ in drive]
    ests = [gt + rng.normal(0.0, 0.7, gt.shape).astype(np.float32) for gt in gts]
    ests = [np.where(_valid(gt), np.abs(est) + 0.01, 1.0).astype(np.float32) for gt, est in
            zip(gts, ests, strict=True)]  # fmt: skip
    for t in (1, 2):  # rows exact in frames 1 and 2: e = 0 there in pair (1, 2)
        rows = gts[t][-20:]  # the road: GT there but for the holes (the sky has none)
        ests[t][-20:] = np.where(_valid(rows), rows, 1.0)
    evaluator = Evaluator(criteria=("all",))
    scorer = TemporalScorer(evaluator, preset="dynamicstereo")
    assert scorer.measures == ("tepe", "tepe_bad_0.5", "tepe_bad_1", "tepe_bad_2", "tepe_bad_3")
    sequences, want = [], []
    for frames in (slice(0, 4), slice(1, 4)):
        g, e = gts[frames], ests[frames]
        pairs = [
            scorer.score(scorer.pair(evaluator.reference(g[t]), g[t + 1]), e[t], e[t + 1])
            for t in range(len(g) - 1)
        ]
        sequences.append(PairScores.combine(pairs))
        want.append((len(g), dynamicstereo_sequence(g, e)))
        in_float32 = dynamicstereo_sequence(g, e, np.float32)
        for name, value in want[-1][1].items():
            assert sequences[-1]["all"][name] == pytest.approx(value, rel=1e-9)
            assert sequences[-1]["all"][name] == pytest.approx(in_float32[name], rel=1e-5)
    total = sum(frames for frames, _ in want)
    averaged = frame_weighted_mean(sequences)["all"]
    for name in scorer.measures:
        value = sum(frames * values[name] for frames, values in want) / total
        assert averaged[name] == pytest.approx(value, rel=1e-9)
    # the presets differ exactly by the pixels whose error is 0
    dispeval = TemporalScorer(evaluator, measures=("tepe",))
    (gt, _), (gt_next, _) = drive[1], drive[2]
    ours = dispeval.score(dispeval.pair(evaluator.reference(gt), gt_next), ests[1], ests[2])
    theirs = scorer.score(scorer.pair(evaluator.reference(gt), gt_next), ests[1], ests[2])
    row = ours.sums[0]
    ratio = row[kernel.PAIR_EVAL] / row[kernel.PAIR_NONZERO]
    assert row[kernel.PAIR_NONZERO] < row[kernel.PAIR_EVAL]
    assert theirs["all"]["tepe"] == pytest.approx(ours["all"]["tepe"] * ratio, rel=1e-12)


# ------------------------------------------------------------------ inputs and registry


def test_the_next_frames_reference_brings_its_all_mask(drive) -> None:
    (gt, est), (gt_next, est_next) = drive[0], drive[1]
    evaluator = Evaluator(criteria=CRITERIA)
    scorer = TemporalScorer(evaluator, measures=MEASURES)
    reference = evaluator.reference(gt)
    mask = np.ones(gt.shape, bool)
    mask[:, : gt.shape[1] // 3] = False
    pair = scorer.pair(reference, evaluator.reference(gt_next, masks={"all": mask}))
    scores = scorer.score(pair, est["bm_fast"], est_next["bm_fast"])
    masked_next = np.where(mask, gt_next, np.nan).astype(np.float32)
    assert_scores(scores, expected(reference, masked_next, est["bm_fast"], est_next["bm_fast"],
                                   "interpolate"))  # fmt: skip


def test_disparity_image_coding_applies_to_both_frames(drive) -> None:
    """A DisparityImage's range (a valid 0, −1 missing) and offset, each frame its own."""
    (gt, est), (gt_next, est_next) = drive[0], drive[1]
    a, b = est["sgbm"], est_next["sgbm"]  # OpenCV: missing = −1, valid ≥ 0
    evaluator = Evaluator(criteria=("all",), missing="thesis")
    scorer = TemporalScorer(evaluator, measures=MEASURES)
    pair = scorer.pair(evaluator.reference(gt), gt_next)
    plain = scorer.score(pair, a, b, est_range=(0, 200))["all"]
    both = _valid(gt) & _valid(gt_next)
    value, value_next = (np.maximum(x, 0.0).astype(np.float64)[both] for x in (a, b))
    change = gt.astype(np.float64)[both] - gt_next.astype(np.float64)[both]
    want = measures_of(np.abs((value - value_next) - change), np.abs(change))
    shifted = scorer.score(pair, a + 2, b + 3, est_range=(2, 200), est_offset=2,
                           next_range=(3, 200), next_offset=3)["all"]  # fmt: skip
    for name in MEASURES:
        assert plain[name] == pytest.approx(want[name], rel=1e-9)
        assert shifted[name] == pytest.approx(want[name], rel=1e-5)


@pytest.mark.parametrize("policy", POLICIES)
def test_prepared_estimates_give_the_same_sums(drive, policy: str) -> None:
    """Each frame prepared once (all before any pair is scored, so none may share a buffer)
    and used in both its pairs: the sums of each pair bit for bit those of the maps."""
    evaluator = Evaluator(criteria=CRITERIA, missing=policy)
    scorer = TemporalScorer(evaluator, measures=MEASURES)
    coding = {"est_range": (0, 200), "est_offset": 0.5}  # OpenCV's −1 holes: missing
    for method in ("bm_fast", "sgbm"):
        maps = [est[method] + np.float32(0.5) for _, est in drive]
        prepared = [scorer.prepare(m, **coding) for m in maps]
        for t, ((gt, _), (gt_next, _)) in enumerate(itertools.pairwise(drive)):
            pair = scorer.pair(evaluator.reference(gt), gt_next)
            plain = scorer.score(pair, maps[t], maps[t + 1], **coding)
            ready = scorer.score(pair, prepared[t], prepared[t + 1])
            mixed = scorer.score(pair, prepared[t], maps[t + 1], **coding)
            assert plain.sums.tobytes() == ready.sums.tobytes() == mixed.sums.tobytes()
            assert plain.to_dict() == ready.to_dict()
    other = TemporalScorer(Evaluator(criteria=CRITERIA, missing="ignore"))
    if policy != "ignore":
        with pytest.raises(ConfigurationError, match=f"prepared under the '{policy}'"):
            other.score(other.pair(evaluator.reference(drive[0][0]), drive[1][0]), *prepared[:2])


def test_bad_input_is_one_clear_error(drive) -> None:
    (gt, est), (gt_next, _) = drive[0], drive[1]
    evaluator = Evaluator(criteria=("all",))
    scorer = TemporalScorer(evaluator)
    reference = evaluator.reference(gt)
    with pytest.raises(ShapeMismatchError, match="the next frame's ground truth is 310×94"):
        scorer.pair(reference, gt_next[::2, ::2])
    pair = scorer.pair(reference, gt_next)
    with pytest.raises(ShapeMismatchError, match="the next frame's estimate is"):
        scorer.score(pair, est["sgbm"], est["sgbm"][:-1])
    with pytest.raises(ConfigurationError, match="unknown temporal preset 'dvsr'"):
        TemporalScorer(evaluator, preset="dvsr")
    with pytest.raises(ConfigurationError, match="unknown pair measure 'mae'"):
        TemporalScorer(evaluator, measures=("tepe", "mae"))
    other = TemporalScorer(Evaluator(criteria=("all",), missing="ignore"))
    parts = [
        scorer.score(pair, est["sgbm"], est["sgbm"]),
        other.score(other.pair(reference, gt_next), est["sgbm"], est["sgbm"]),
    ]
    with pytest.raises(ConfigurationError, match="cannot combine"):
        PairScores.combine(parts)


def test_pair_measures_stay_out_of_the_frame_registry() -> None:
    """No frame front end lists, parses or scores them (the golden outputs do not change)."""
    from dispeval_ros.core import measures

    for name in registry.PAIR_MEASURE_NAMES:
        assert name not in registry.BY_NAME
        assert name not in registry.MEASURE_NAMES
        with pytest.raises(ConfigurationError):
            measures.parse_measures([name.replace("_X", "_1")])
    for measure in registry.PAIR_MEASURES:
        assert measure.needs == registry.NEEDS_GT_PAIR
        assert measure.unit
        assert measure.description
        assert measure.family == "temporal"
        for name in (measure.num, measure.den):
            assert name is None or name in registry.PAIR_SUM_FIELDS
    constants = {
        "n_pair": kernel.PAIR_N,
        "n_pair_eval": kernel.PAIR_EVAL,
        "n_pair_nonzero": kernel.PAIR_NONZERO,
        "sum_te": kernel.PAIR_SUM_TE,
        "sum_te_rel": kernel.PAIR_SUM_TE_REL,
        "te_bad_count_0": kernel.PAIR_BAD,
    }
    for name, index in constants.items():
        assert registry.PAIR_SUM_FIELDS[index] == name
    assert len(registry.PAIR_SUM_FIELDS) == kernel.PAIR_COUNT
    assert registry.TEPE_R_EPSILON == EPSILON
