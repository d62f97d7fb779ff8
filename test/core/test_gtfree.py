"""Ground-truth-free measures (vpe, lrc) and criteria (all, roi, texture) against plain loops.

The reference here is written from the definitions, pixel by pixel: the estimate after the
missing policy (``interpolate``: the KITTI devkit's background interpolation, a port shared
with test_real_scenes; ``thesis``: 0; ``ignore``: left out), a z-buffer per row of the largest
disparity landing on each right-view column ``floor(x − d + 0.5)`` (occluded when it exceeds
``d + 1``), the target ``x − d`` inside ``[0, W − 1]``, the right image linearly interpolated
there, and the mean absolute difference to the left image.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
from reference import POLICIES, scored_estimate

from dispeval_ros.cli.main import main
from dispeval_ros.core.criteria import texture_set
from dispeval_ros.core.evaluator import Evaluator
from dispeval_ros.core.gtfree import GroundTruthFree, concordance, joined, kendall_tau
from dispeval_ros.core.measures import Scores
from dispeval_ros.errors import InputError, ShapeMismatchError
from dispeval_ros.io import load_scene, write_pfm
from dispeval_ros.testbed.methods import default_methods


def loop_measures(
    left: np.ndarray,
    right: np.ndarray,
    est: np.ndarray,
    policy: str,
    right_est: np.ndarray | None = None,
    region: np.ndarray | None = None,
) -> dict[str, float]:
    """vpe, lrc and density of one estimate over ``region`` (default: every pixel), by loops."""
    height, width = left.shape
    values, takes_part = scored_estimate(est.astype(np.float64), policy)
    if right_est is not None:
        right_values, right_part = scored_estimate(right_est.astype(np.float64), policy)
    region = np.ones(left.shape, bool) if region is None else region
    total = count = checked = inconsistent = 0.0
    for y in range(height):
        nearest = [-math.inf] * width
        for x in range(width):
            if takes_part[y, x]:
                t = math.floor(x - values[y, x] + 0.5)
                if 0 <= t < width:
                    nearest[t] = max(nearest[t], values[y, x])
        for x in range(width):
            if not region[y, x] or not takes_part[y, x]:
                continue
            d = values[y, x]
            source = x - d
            if source < 0 or source > width - 1:
                continue
            t = math.floor(source + 0.5)
            if right_est is not None and right_part[y, t]:
                checked += 1
                inconsistent += abs(d - right_values[y, t]) > 1.0
            if nearest[t] > d + 1.0:
                continue
            x0 = min(math.floor(source), width - 1)
            x1 = min(x0 + 1, width - 1)
            a = source - x0
            predicted = (1 - a) * float(right[y, x0]) + a * float(right[y, x1])
            total += abs(float(left[y, x]) - predicted)
            count += 1
    valid = np.isfinite(est) & (est > 0)
    return {
        "vpe": total / count if count else math.nan,
        "lrc": 100.0 * inconsistent / checked if checked else math.nan,
        "density": float(valid[region].sum()) / region.sum() if region.any() else math.nan,
        "n": float(region.sum()),
    }


def texture(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """A smooth, strongly textured intensity pattern defined at any real position."""
    return (
        128
        + 55 * np.sin(0.37 * x + 0.4 * y)
        + 35 * np.sin(0.23 * x - 0.61 * y)
        + 20 * np.cos(0.5 * x + 0.11 * y * x / 40)
    )


def synthetic_pair(
    height: int = 40, width: int = 90, d0: float = 6.25, slope: float = 0.03
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Left and right 8-bit images of a slanted plane ``d(x) = d0 + slope·x`` and its disparity.

    The right image is the exact warp of the left texture: the right pixel ``u`` sees the left
    position ``x`` with ``x − d(x) = u``, i.e. ``x = (u + d0) / (1 − slope)``.
    """
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float64)
    left = np.clip(np.round(texture(xs, ys)), 0, 255).astype(np.uint8)
    right = np.clip(np.round(texture((xs + d0) / (1 - slope), ys)), 0, 255).astype(np.uint8)
    disparity = (d0 + slope * xs).astype(np.float32)
    return left, right, disparity


def free_scores(
    left: np.ndarray,
    right: np.ndarray,
    est: np.ndarray,
    policy: str,
    right_est: np.ndarray | None = None,
    criteria: tuple[str, ...] = ("all",),
) -> Scores:
    free = GroundTruthFree(criteria, policy)
    return free.score(free.pair(left, right), est, est_right=right_est)


def test_true_disparity_predicts_the_right_view() -> None:
    left, right, disparity = synthetic_pair()
    exact = free_scores(left, right, disparity, "interpolate")["gtfree:all"]["vpe"]
    off = free_scores(left, right, disparity + 2, "interpolate")["gtfree:all"]["vpe"]
    assert exact < 1.0  # rounding to 8 bit and linear interpolation of a smooth texture
    assert off > 10 * exact
    assert off > 20.0
    assert exact == pytest.approx(loop_measures(left, right, disparity, "interpolate")["vpe"])


@pytest.mark.parametrize("policy", POLICIES)
def test_vpe_and_lrc_match_loops_with_holes_and_occlusions(policy: str) -> None:
    left, right, disparity = synthetic_pair(30, 70)
    rng = np.random.default_rng(3)
    est = disparity + rng.normal(0, 1.5, disparity.shape).astype(np.float32)
    est[:, 30:36] += 9  # a nearer strip: hides pixels on its left (z-buffer)
    est[rng.random(est.shape) < 0.15] = 0  # holes
    est[5, :] = np.nan  # an empty row
    est[:, :3] = -1  # invalid border (OpenCV's min_disparity − 1)
    right_est = np.roll(est, -6, axis=1) + rng.normal(0, 0.6, est.shape).astype(np.float32)
    scores = free_scores(left, right, est, policy, right_est)["gtfree:all"]
    expected = loop_measures(left, right, est, policy, right_est)
    for name in ("vpe", "lrc", "density", "n"):
        assert scores[name] == pytest.approx(expected[name], rel=1e-9), name
    assert 0 < expected["lrc"] < 100


def test_estimate_range_and_inf_are_missing() -> None:
    left, right, disparity = synthetic_pair(20, 50)
    est = disparity.copy()
    est[:, 10:15] = np.inf
    free = GroundTruthFree(("all",), "ignore")
    pair = free.pair(left, right)
    clipped = free.score(pair, est, est_range=(0.0, 7.0))["gtfree:all"]
    limited = np.where(est <= 7.0, est, 0).astype(np.float32)
    assert clipped["vpe"] == pytest.approx(loop_measures(left, right, limited, "ignore")["vpe"])
    assert clipped["density"] == pytest.approx(float((limited > 0).mean()))


def test_texture_criteria_match_a_loop_and_partition_every_pixel() -> None:
    rng = np.random.default_rng(5)
    image = np.full((24, 40), 100, np.uint8)
    image[:, 20:] = rng.integers(0, 256, (24, 20))
    image[10:14, 5:9] = rng.integers(95, 106, (4, 4))  # noise of ±5 grey levels: textured
    labels = texture_set(image).labels
    grey = image.astype(np.float64)
    expected = np.zeros(image.shape, np.int32)
    height, width = image.shape
    for y in range(height):
        for x in range(width):
            total = 0.0
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    yy = abs(y + dy) if y + dy >= 0 else -(y + dy)
                    yy = 2 * (height - 1) - yy if yy > height - 1 else yy
                    xx = abs(x + dx)
                    xx = 2 * (width - 1) - xx if xx > width - 1 else xx
                    g = grey[yy, xx + 1] - grey[yy, xx] if xx + 1 < width else 0.0
                    total += g * g
            expected[y, x] = 1 if total / 9 < 4.0 else 0
    assert np.array_equal(labels, expected)
    assert labels[:7, :18].all()
    assert not labels[:, 22:].any()
    scores = free_scores(
        image, image, np.full(image.shape, 0.5, np.float32), "thesis", criteria=("all", "texture")
    )
    assert scores["gtfree:textured"]["n"] + scores["gtfree:textureless"]["n"] == image.size
    region = expected == 1
    assert scores["gtfree:textureless"]["vpe"] == pytest.approx(
        loop_measures(image, image, np.full(image.shape, 0.5, np.float32), "thesis", region=region)[
            "vpe"
        ]
    )


def test_joined_scores_keep_gt_and_gt_free_measures_apart() -> None:
    left, right, disparity = synthetic_pair(30, 60)
    gt = Evaluator(("all",), ("bmp", "sze", "density")).score(disparity, disparity + 0.5)
    free = free_scores(left, right, disparity + 0.5, "interpolate", criteria=("all", "texture"))
    both = joined(gt, free)
    assert both.criteria == ("all", "gtfree:all", "gtfree:textured", "gtfree:textureless")
    assert math.isnan(both["all"]["vpe"])
    assert math.isnan(both["gtfree:all"]["sze"])
    assert both["gtfree:all"]["vpe"] == free["gtfree:all"]["vpe"]
    assert both["all"]["sze"] == gt["all"]["sze"]
    combined = Scores.combine([both, both])
    assert combined["gtfree:all"]["vpe"] == pytest.approx(free["gtfree:all"]["vpe"])


def test_bad_images_are_one_line() -> None:
    free = GroundTruthFree()
    grey = np.zeros((10, 12), np.uint8)
    with pytest.raises(InputError, match="8-bit grey image"):
        free.pair(np.zeros((10, 12, 3), np.uint8), grey)
    with pytest.raises(InputError, match="8-bit grey image"):
        free.pair(grey, grey.astype(np.uint16))
    with pytest.raises(InputError, match="1 px wide: at least 2"):
        free.pair(grey[:, :1], grey[:, :1])
    with pytest.raises(ShapeMismatchError, match="right image is 11×10"):
        free.pair(grey, np.zeros((10, 11), np.uint8))
    with pytest.raises(ShapeMismatchError, match="estimate is 12×9"):
        free.score(free.pair(grey, grey), np.zeros((9, 12), np.float32))


REAL = [
    ("middlebury-2001-2003/cones", (slice(100, 180), slice(150, 330))),
    ("middeval3-training-Q/Adirondack", (slice(200, 260), slice(300, 520))),
    ("kitti-2015/000005_10", (slice(200, 250), slice(500, 800))),
    ("eth3d-two-view/playground", (slice(100, 150), slice(200, 450))),
]


@pytest.mark.parametrize(("name", "window"), REAL, ids=[name for name, _ in REAL])
def test_real_pairs_match_loops_and_gt_beats_a_shift(
    shared_data: Path, name: str, window: tuple[slice, slice]
) -> None:
    """On real pairs, SGBM's vpe equals the loops' (on a crop), and the GT predicts better
    than the GT shifted by 2 px."""
    scene = load_scene(shared_data / name)
    assert scene.left is not None
    assert scene.right is not None
    left = cv2.imread(str(scene.left), cv2.IMREAD_GRAYSCALE)[window]
    right = cv2.imread(str(scene.right), cv2.IMREAD_GRAYSCALE)[window]
    full_left = cv2.imread(str(scene.left), cv2.IMREAD_GRAYSCALE)
    full_right = cv2.imread(str(scene.right), cv2.IMREAD_GRAYSCALE)
    method = next(m for m in default_methods(full_left.shape[1]) if m.name == "sgbm")
    est = method.compute(full_left, full_right)[window]
    for policy in POLICIES:
        scores = free_scores(left, right, est, policy)["gtfree:all"]
        expected = loop_measures(left, right, est, policy)
        assert scores["vpe"] == pytest.approx(expected["vpe"], rel=1e-9), policy
    gt = np.where(np.isfinite(scene.gt) & (scene.gt > 0), scene.gt, 0).astype(np.float32)
    free = GroundTruthFree(("all",), "ignore")
    pair = free.pair(full_left, full_right)
    true_vpe = free.score(pair, gt)["gtfree:all"]["vpe"]
    shifted = np.where(gt > 0, gt + 2, 0).astype(np.float32)
    assert free.score(pair, shifted)["gtfree:all"]["vpe"] > 1.1 * true_vpe


# ------------------------------------------------------------------------------ dispeval eval


@pytest.fixture
def pair_files(tmp_path: Path) -> dict[str, Path]:
    """The synthetic pair as PNGs, its true disparity, a 2-px-off one and a right-view one."""
    left, right, disparity = synthetic_pair(40, 90)
    files = {"left": tmp_path / "left.png", "right": tmp_path / "right.png"}
    cv2.imwrite(str(files["left"]), left)
    cv2.imwrite(str(files["right"]), right)
    cv2.imwrite(str(tmp_path / "colour.png"), cv2.cvtColor(right, cv2.COLOR_GRAY2BGR))
    files["colour"] = tmp_path / "colour.png"
    for name, values in (("true", disparity), ("off", disparity + 2), ("gt", disparity)):
        files[name] = tmp_path / f"{name}.pfm"
        write_pfm(files[name], values)
    files["true_right"] = tmp_path / "true_right.pfm"
    write_pfm(files["true_right"], np.roll(disparity, -6, axis=1))
    return files


def eval_json(capsys: pytest.CaptureFixture[str], *argv: str) -> dict:
    assert main(["eval", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_eval_without_gt_keeps_the_json_shape_and_ranks_by_vpe(
    capsys: pytest.CaptureFixture[str], pair_files: dict[str, Path]
) -> None:
    files = pair_files
    images = ["--left-image", str(files["left"]), "--right-image", str(files["right"])]
    document = eval_json(
        capsys,
        *images,
        "--est",
        f"true={files['true']}",
        "--est",
        f"off={files['off']}",
        "--est-right",
        f"true={files['true_right']}",
    )
    with_gt = eval_json(capsys, "--gt", str(files["gt"]), "--est", str(files["true"]))
    assert set(with_gt) <= set(document)  # same keys (gt_free added)
    left, right, disparity = synthetic_pair(40, 90)
    frames = {f["method"]: f["criteria"] for f in document["frames"]}
    assert set(frames["true"]) == {"gtfree:all", "gtfree:textured", "gtfree:textureless"}
    expected = loop_measures(left, right, disparity, "interpolate")
    assert frames["true"]["gtfree:all"]["vpe"] == pytest.approx(expected["vpe"])
    assert frames["off"]["gtfree:all"]["vpe"] > 10 * frames["true"]["gtfree:all"]["vpe"]
    assert frames["true"]["gtfree:all"]["lrc"] is not None
    assert frames["off"]["gtfree:all"]["lrc"] is None  # no right-view estimate
    assert document["objectives"][0] == "gtfree:all/vpe"
    assert document["models"]["groups"]["true"] == 1
    assert document["gt_free"]["in_objectives"] is True


def test_gt_free_measures_stay_out_of_gt_objectives_unless_asked(
    capsys: pytest.CaptureFixture[str], pair_files: dict[str, Path]
) -> None:
    files = pair_files
    argv = [
        "--gt",
        str(files["gt"]),
        "--left-image",
        str(files["left"]),
        "--right-image",
        str(files["right"]),
        "--est",
        str(files["true"]),
        "--est",
        str(files["off"]),
        "--criteria",
        "all",
    ]
    plain = eval_json(capsys, *argv)
    assert plain["objectives"] == ["all/sze", "all/bmpre"]
    assert plain["gt_free"]["in_objectives"] is False
    frame = plain["frames"][0]["criteria"]
    assert frame["all"]["vpe"] is None
    assert frame["gtfree:all"]["sze"] is None
    asked = eval_json(capsys, *argv, "--gt-free-objectives")
    assert asked["objectives"][:2] == ["all/sze", "all/bmpre"]
    assert "gtfree:all/vpe" in asked["objectives"]
    assert main(["eval", *argv]) == 0
    text = capsys.readouterr().out
    assert "criterion: gtfree:all  (ground-truth-free" in text
    assert "vpe [grey levels]" in text


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"right": "colour"}, "is grey but .*colour.png is colour"),
        ({"est": "gt_small"}, "the estimate is 30×20 but the images are 90×40"),
        ({"drop_right": True}, "give both --left-image and --right-image"),
    ],
)
def test_eval_bad_images_are_one_line(
    capsys: pytest.CaptureFixture[str],
    pair_files: dict[str, Path],
    tmp_path: Path,
    change: dict,
    message: str,
) -> None:
    write_pfm(tmp_path / "gt_small.pfm", np.ones((20, 30), np.float32))
    pair_files["gt_small"] = tmp_path / "gt_small.pfm"
    argv = ["eval", "--left-image", str(pair_files["left"])]
    if not change.get("drop_right"):
        argv += ["--right-image", str(pair_files[change.get("right", "right")])]
    argv += ["--est", str(pair_files[change.get("est", "true")])]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert re.search(message, err), err


def test_kendall_tau_by_hand() -> None:
    assert kendall_tau([1, 2, 3], [10, 20, 30]) == 1.0
    assert kendall_tau([1, 2, 3], [3, 2, 1]) == -1.0
    assert kendall_tau([1, 2, 3, 4], [1, 3, 2, 4]) == pytest.approx(4 / 6)  # 5 alike, 1 not
    # a tie in the first ranking: τ-b = 2 / sqrt(2 · 3) (scipy.stats.kendalltau agrees)
    assert kendall_tau([1, 1, 2], [1, 2, 3]) == pytest.approx(2 / math.sqrt(6))
    assert math.isnan(kendall_tau([1, 1, 1], [1, 2, 3]))
    assert concordance([1, 1, 2], [1, 2, 3]) == (2, 0, 1, 0)


def test_gt_free_criteria_are_checked(
    capsys: pytest.CaptureFixture[str], pair_files: dict[str, Path]
) -> None:
    from dispeval_ros.errors import ConfigurationError

    with pytest.raises(ConfigurationError, match="unknown ground-truth-free criterion set 'depth'"):
        GroundTruthFree(("all", "depth"))
    images = ["--left-image", str(pair_files["left"]), "--right-image", str(pair_files["right"])]
    argv = ["eval", *images, "--est", str(pair_files["true"]), "--gt-free-criteria", "visibility"]
    assert main(argv) == 2
    assert "criterion set 'visibility'" in capsys.readouterr().err


def test_criteria_of_the_same_left_image_are_reused_by_content() -> None:
    """A left image seen again reuses its criteria; another image, or the caller changing its
    array in place afterwards, builds them again (the numbers stay the loops')."""
    left, right, disparity = synthetic_pair(30, 60)
    other = np.ascontiguousarray(left[:, ::-1])
    free = GroundTruthFree(("all", "texture"), "interpolate")
    first = free.pair(left, right)
    assert free.pair(left.copy(), right).partition is first.partition
    assert free.pair(other, right).partition is not first.partition
    again = free.pair(left, right)
    assert again.partition is not first.partition
    assert np.array_equal(again.partition.cells, first.partition.cells)
    buffer = left.copy()
    reused = free.pair(buffer, right)
    buffer[:, :30] = 100  # the caller reuses its image buffer for the next frame
    changed = free.pair(buffer, right)
    assert changed.partition is not reused.partition
    region = texture_set(buffer).labels == 1
    assert free.score(changed, disparity)["gtfree:textureless"]["vpe"] == pytest.approx(
        loop_measures(buffer, right, disparity, "interpolate", region=region)["vpe"], rel=1e-9
    )


def test_occlusion_tolerance_must_not_be_negative() -> None:
    from dispeval_ros.errors import ConfigurationError

    with pytest.raises(ConfigurationError, match="occlusion tolerance must be at least 0 px"):
        GroundTruthFree(occlusion_tolerance=-0.5)
    with pytest.raises(ConfigurationError, match="occlusion tolerance"):
        GroundTruthFree(occlusion_tolerance=math.nan)
