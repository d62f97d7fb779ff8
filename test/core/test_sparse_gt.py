"""Sparse GT as first-class input: sparse boundaries and the depth-domain measures."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from dispeval_ros.core import Camera, Evaluator, Scores
from dispeval_ros.core import criteria as crit
from dispeval_ros.core.kernels import FIELD_SUM_EZ, FIELD_SUM_EZ2, FIELD_SUM_IZ2, FIELD_SUM_RELZ
from dispeval_ros.core.measures import DEPTH_MEASURES, SUM_FIELDS, parse_measures
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.io.scenes import list_frames

# -- sparse boundary ----------------------------------------------------------------------


def loop_sparse_boundary(gt: np.ndarray, valid: np.ndarray, gap: float, width: int) -> np.ndarray:
    """Straightforward definition: a valid point with a valid window neighbour > gap away."""
    half = width // 2
    out = np.zeros(gt.shape, bool)
    for y, x in zip(*np.nonzero(valid), strict=True):
        window = (slice(max(y - half, 0), y + half + 1), slice(max(x - half, 0), x + half + 1))
        near = gt[window][valid[window]]
        out[y, x] = bool((np.abs(near - gt[y, x]) > gap).any())
    return out


def lidar_like(seed: int = 0) -> np.ndarray:
    """Scan rows every 4 px, a point every 2 px: a 30-px wall, a 60-px object in the middle."""
    rng = np.random.default_rng(seed)
    gt = np.zeros((40, 60), np.float32)
    gt[2::4, 1::2] = 30.0 + rng.uniform(-0.3, 0.3, gt[2::4, 1::2].shape)
    gt[10:30:4, 21:40:2] = 60.0
    return gt


def test_sparse_boundary_matches_the_loop_and_dense_rule_finds_nothing() -> None:
    gt = lidar_like()
    valid = gt > 0
    assert crit.is_sparse(valid)
    expected = loop_sparse_boundary(gt, valid, 2.0, 9)
    np.testing.assert_array_equal(crit.sparse_discontinuities(gt, valid, 2.0, 9), expected)
    assert expected.sum() > 0
    # Object points next to the wall and wall points next to the object, nothing far away.
    assert expected[10, 21]
    assert expected[10, 19]
    assert not expected[2, 1]
    assert not expected[18, 29]  # the object's middle: the wall is > 4 px away
    assert not crit.discontinuities(gt, valid, 2.0, 9).any()  # the old rule is blind here
    auto = Evaluator(criteria=("visibility",)).reference(gt)
    dense = Evaluator(criteria=("visibility",), boundary_mode="dense").reference(gt)
    assert (
        auto.partition.counts()["boundary"] + auto.partition.counts()["occluded"]
        >= int(expected.sum()) - auto.partition.counts()["occluded"]
    )
    np.testing.assert_array_equal(auto.partition.mask("boundary"), expected & ~_occluded(auto))
    assert dense.partition.counts()["boundary"] == 0
    with pytest.raises(ConfigurationError, match="boundary mode"):
        Evaluator(boundary_mode="lidar")


def _occluded(reference: object) -> np.ndarray:
    return reference.partition.mask("occluded")  # type: ignore[attr-defined]


def test_dense_gt_keeps_the_dense_rule() -> None:
    rng = np.random.default_rng(3)
    gt = np.full((50, 70), 20.0, np.float32)
    gt[10:30, 20:40] = 40.0
    gt[rng.random(gt.shape) < 0.05] = 0  # a few holes
    valid = gt > 0
    assert not crit.is_sparse(valid)
    auto = Evaluator(criteria=("visibility",)).reference(gt)
    dense = Evaluator(criteria=("visibility",), boundary_mode="dense").reference(gt)
    np.testing.assert_array_equal(auto.partition.cells, dense.partition.cells)


@pytest.mark.data
@pytest.mark.parametrize(
    "folder",
    [
        "middlebury-2001-2003/tsukuba",
        "kitti-2015/000005_10",
        "kitti-2015/devkit_demo",
        "eth3d-two-view/playground",
        "middlebury-2014-motorcycle-quarter",
        "middeval3-training-Q/Adirondack",
    ],
)
def test_real_dense_and_semi_dense_gt_unchanged(shared_data: Path, folder: str) -> None:
    scene = list_frames(shared_data / folder)[0]
    valid = np.isfinite(scene.gt) & (scene.gt > 0)
    assert not crit.is_sparse(valid)


@pytest.mark.data
def test_real_lidar_gt_has_boundaries(shared_data: Path) -> None:
    scene = list_frames(shared_data / "kitti-lidar" / "kitti2015-with-velodyne")[0]
    evaluator = Evaluator(criteria=("visibility",))
    counts = evaluator.reference(scene.gt, scene.camera).partition.counts()
    dense = Evaluator(criteria=("visibility",), boundary_mode="dense")
    dense_counts = dense.reference(scene.gt, scene.camera).partition.counts()
    total = sum(counts.values())
    # KITTI 000010 with the default parallax filter: 905 of 19,473 points (4.6 %); the
    # 4-neighbour rule finds none (a scan's points have no valid vertical neighbours).
    assert 0.02 * total < counts["boundary"] < 0.2 * total
    assert dense_counts["boundary"] < 0.002 * total


# -- depth-domain measures ----------------------------------------------------------------


def test_depth_measures_hand_worked() -> None:
    camera = Camera(f=100.0, baseline=1.0)  # f·B = 100: Z = 100 / d
    gt = np.array([[10.0, 20.0]], np.float32)  # Z = 10 m, 5 m
    est = np.array([[20.0, 20.0]], np.float32)  # Z = 5 m, 5 m
    scores = Evaluator(criteria=("all",), measures=DEPTH_MEASURES).score(gt, est, camera)["all"]
    assert scores["mae_z"] == pytest.approx(2.5)  # (5 + 0) / 2
    assert scores["rmse_z"] == pytest.approx(math.sqrt(12.5))
    assert scores["absrel_z"] == pytest.approx(0.25)  # (5/10 + 0) / 2
    # 1/Z: 0.1 vs 0.2 per metre → 100 per km; RMS over two points: 100/√2.
    assert scores["irmse"] == pytest.approx(100 / math.sqrt(2))


def numpy_depth_measures(
    gt: np.ndarray, est: np.ndarray, camera: Camera, missing: str, mu: float = 0.01
) -> dict[str, float]:
    """The depth measures straight from their definitions, per missing policy."""
    valid_gt = np.isfinite(gt) & (gt > 0)
    present = np.isfinite(est) & (est > 0)
    if missing == "interpolate":
        filled = Evaluator(missing="interpolate").normalise(est)
        values = np.abs(filled).astype(np.float64)
    else:
        values = np.where(present, est, 0.0).astype(np.float64)
    d = gt[valid_gt].astype(np.float64)
    e = values[valid_gt]
    keep = present[valid_gt] if missing == "ignore" else np.ones(d.shape, bool)
    d, e = d[keep], e[keep]
    z_gt = camera.fb / np.maximum(d + camera.doffs, mu)
    z_est = camera.fb / np.maximum(e + camera.doffs, mu)
    err = np.abs(z_est - z_gt)
    return {
        "mae_z": float(err.mean()),
        "rmse_z": float(np.sqrt((err**2).mean())),
        "absrel_z": float((err / z_gt).mean()),
        "irmse": float(1000 * np.sqrt(((1 / z_est - 1 / z_gt) ** 2).mean())),
    }


@pytest.mark.parametrize("missing", ["interpolate", "thesis", "ignore"])
def test_depth_measures_every_policy_and_sequences_exact(missing: str) -> None:
    rng = np.random.default_rng(11)
    camera = Camera(f=700.0, baseline=0.5, doffs=2.5)
    evaluator = Evaluator(
        criteria=("all", "depth"),
        measures=("mae", *DEPTH_MEASURES),
        missing=missing,
        depth_ranges=[(0, 10), (10, 30), (30, math.inf)],
    )
    frames = []
    for _ in range(3):
        gt = rng.uniform(3, 80, (30, 40)).astype(np.float32)
        gt[rng.random(gt.shape) < 0.7] = 0  # sparse GT
        est = (gt + rng.normal(0, 1.5, gt.shape)).astype(np.float32)
        est[rng.random(gt.shape) < 0.1] = np.nan  # missing estimates
        frames.append((gt, est))
        scores = evaluator.score(gt, est, camera)
        expected = numpy_depth_measures(gt, est, camera, missing)
        for name, value in expected.items():
            assert scores["all"][name] == pytest.approx(value, rel=1e-9), name
    combined = Scores.combine([evaluator.score(gt, est, camera) for gt, est in frames])
    stacked = numpy_depth_measures(
        np.vstack([f[0] for f in frames]), np.vstack([f[1] for f in frames]), camera, missing
    )
    if missing != "interpolate":  # interpolation is per frame, stacking would change it
        for name, value in stacked.items():
            assert combined["all"][name] == pytest.approx(value, rel=1e-9), name
    per_range = sum(combined[c]["n"] for c in ("0-10m", "10-30m", "30+m"))
    assert per_range == combined["all"]["n"]


@pytest.mark.parametrize("missing", ["interpolate", "thesis", "ignore"])
def test_depth_terms_only_when_asked_and_disparity_sums_unchanged(missing: str) -> None:
    """The scoring pass skips the depth-domain sums unless a depth measure is asked for; the
    disparity-domain sums are bit-identical either way (the two loops share their terms)."""
    rng = np.random.default_rng(5)
    camera = Camera(f=700.0, baseline=0.5, doffs=2.5)
    gt = rng.uniform(3, 80, (40, 50)).astype(np.float32)
    gt[rng.random(gt.shape) < 0.2] = np.nan
    est = (gt + rng.normal(0, 2.0, gt.shape)).astype(np.float32)
    est[rng.random(gt.shape) < 0.1] = 0
    disparity = ("bmp", "mae", "mse", "mre", "sze", "bmpre", "d1", "density")
    plain = Evaluator(("all", "depth"), disparity, missing=missing).score(gt, est, camera)
    both = Evaluator(("all", "depth"), (*disparity, *DEPTH_MEASURES), missing=missing).score(
        gt, est, camera
    )
    depth_columns = [FIELD_SUM_EZ, FIELD_SUM_EZ2, FIELD_SUM_RELZ, FIELD_SUM_IZ2]
    assert not plain.sums[:, depth_columns].any()
    assert both.sums[:, depth_columns].all()
    kept = [c for c in range(plain.sums.shape[1]) if c not in depth_columns]
    assert np.array_equal(plain.sums[:, kept], both.sums[:, kept])
    for name in disparity:
        assert plain["all"][name] == both["all"][name], name


def test_depth_measure_names() -> None:
    assert parse_measures(["irmse", "mae_z"]) == ("irmse", "mae_z")
    depth = SUM_FIELDS.index("sum_ez")
    assert SUM_FIELDS[depth : depth + 4] == ("sum_ez", "sum_ez2", "sum_relz", "sum_iz2")
    with pytest.raises(ConfigurationError, match="mae_z"):
        parse_measures(["mae_m"])
