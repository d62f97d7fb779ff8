"""Official protocols against straightforward re-computations of the official tools' formulas.

Each expected number is computed here pixel by pixel (Python loops over numpy float32 scalars,
which round like C ``float``), from the formulas of the official sources: MiddEval3 SDK
``evaldisp.cpp``, KITTI 2015 devkit ``evaluate_scene_flow.cpp`` / ``io_disp.h``, KITTI 2012
devkit ``evaluate_stereo.cpp`` / ``utils.h`` (``statMean``), ETH3D ``two-view-evaluation``
``main.cc`` (``ComputeMetrics``). The library must give the same numbers exactly.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from dispeval_ros.cli.main import main
from dispeval_ros.core.evaluator import Evaluator
from dispeval_ros.core.protocols import (
    MIDDEVAL3_WEIGHTS,
    eth3d_frame,
    evaluate_frame,
    get_protocol,
    kitti2012_frame,
    kitti2015_frame,
    kitti_interpolation,
    middeval3_frame,
    quantile_index,
    summarize_frames,
)
from dispeval_ros.io import read_disparity, read_mask, write_disparity_png16, write_pfm
from dispeval_ros.io.benchmarks import discover, find_estimate, load_frame, read_estimate
from dispeval_ros.offline.benchmark import evaluate_benchmark, evaluate_frames, single_frame
from dispeval_ros.testbed.methods import default_methods

F = np.float32
VELODYNE = "kitti-lidar/kitti2015-with-velodyne"
MIDDEVAL3 = "middeval3-training-Q"


# ------------------------------------------------------------------------ re-computations


def devkit_interpolation(estimate: np.ndarray) -> np.ndarray:
    """io_disp.h interpolateBackground: invalid = −1; gaps min of both ends; extend rows, columns."""
    d = np.where(np.isfinite(estimate) & (estimate > 0), estimate, -1.0).astype(F)
    height, width = d.shape
    for v in range(height):
        count = 0
        for u in range(width):
            if d[v, u] >= 0:
                if count >= 1:
                    u1, u2 = u - count, u - 1
                    if u1 > 0 and u2 < width - 1:
                        d[v, u1 : u2 + 1] = min(d[v, u1 - 1], d[v, u2 + 1])
                count = 0
            else:
                count += 1
        valid = np.flatnonzero(d[v] >= 0)
        if valid.size:
            d[v, : valid[0]] = d[v, valid[0]]
            d[v, valid[-1] + 1 :] = d[v, valid[-1]]
    for u in range(width):
        valid = np.flatnonzero(d[:, u] >= 0)
        if valid.size:
            d[: valid[0], u] = d[valid[0], u]
            d[valid[-1] + 1 :, u] = d[valid[-1], u]
    return d


def devkit_d1_counters(gt: np.ndarray, estimate: np.ndarray, obj: np.ndarray | None) -> list[int]:
    """disparityErrorsOutlier: the 12 counters, pixel by pixel in float32."""
    ipol = devkit_interpolation(estimate)
    counters = [0] * 12
    height, width = gt.shape
    for u in range(width):
        for v in range(height):
            d_gt = F(gt[v, u])
            if not d_gt > 0:
                continue
            e = F(abs(d_gt - ipol[v, u]))
            outlier = e > 3.0 and float(F(e / abs(d_gt))) > 0.05
            fg = obj is not None and obj[v, u] > 0
            has = bool(np.isfinite(estimate[v, u]) and estimate[v, u] > 0)
            for part in (1 if fg else 0, 2):
                counters[4 * part + 0] += outlier
                counters[4 * part + 1] += 1
                counters[4 * part + 2] += outlier and has
                counters[4 * part + 3] += has
    return counters


def ratio32(a: float, b: float) -> float:
    return 100.0 * float(F(F(a) / max(F(b), F(1.0))))


def d1_values(c: list[float], foreground: bool = True) -> dict[str, float]:
    out = {}
    for i, part in enumerate(("bg", "fg", "all")):
        known = foreground or part == "all"
        out[f"D1-{part}"] = ratio32(c[4 * i], c[4 * i + 1]) if known else math.nan
        out[f"D1-{part} (est)"] = ratio32(c[4 * i + 2], c[4 * i + 3]) if known else math.nan
    out["density"] = ratio32(c[11], c[9])
    return out


def assert_same(have: dict[str, float], want: dict[str, float]) -> None:
    for column, value in want.items():
        if math.isnan(value):
            assert math.isnan(have[column]), column
        else:
            assert have[column] == value, (
                f"{column}: library {have[column]!r}, recomputed {value!r}"
            )


@functools.cache
def stereo_estimate(left: Path, right: Path, invalid: float) -> np.ndarray:
    """The testbed's OpenCV SGBM on a real pair; its holes set to ``invalid``."""
    sgbm = next(m for m in default_methods(1242) if m.name == "sgbm")
    image_l = cv2.imread(str(left), cv2.IMREAD_GRAYSCALE)
    image_r = cv2.imread(str(right), cv2.IMREAD_GRAYSCALE)
    estimate = sgbm.compute(image_l, image_r)
    return np.where(estimate > 0, estimate, F(invalid)).astype(F)


def run_json(capsys: pytest.CaptureFixture[str], *argv: str) -> dict:
    assert main(["eval", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


# --------------------------------------------------------------------------- KITTI 2015


def test_interpolation_leaves_empty_rows_at_minus_one() -> None:
    estimate = np.full((5, 6), 10.0, F)
    estimate[2] = 0.0  # a row without estimate between estimated rows
    estimate[0, 1:3] = 0.0
    estimate[0, 2] = 4.0
    filled = kitti_interpolation(estimate)
    np.testing.assert_array_equal(filled, devkit_interpolation(estimate))
    assert (filled[2] == -1).all()
    assert filled[0, 1] == 4.0  # gap takes the smaller neighbour
    assert (kitti_interpolation(np.zeros((3, 4), F)) == -1).all()


def test_kitti2015_exactly_five_percent_is_an_outlier() -> None:
    """e/d = 5/100 in float32 is 0.05f > 0.05 (double): the devkit counts it, exact math not."""
    gt = np.full((4, 4), 100.0, F)
    estimate = np.full((4, 4), 95.0, F)
    result = kitti2015_frame("x", gt, None, estimate, np.zeros((4, 4), np.uint8))
    assert result.values["occ"]["D1-all"] == 100.0
    exact = Evaluator(criteria=("all",), measures=("d1",)).score(gt, estimate)
    assert exact["all"]["d1"] == 0.0


def kitti_frames(root: Path) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray | None]]:
    base = root / VELODYNE
    frames = []
    for name in ("000010", "000043", "000112", "000150"):
        gt = read_disparity(base / "gt/disp_occ_0" / f"{name}.png")
        est = read_disparity(base / "prediction" / f"{name}.png")
        obj = read_mask(base / "gt/obj_map" / f"{name}.png")
        frames.append((name, gt, est, obj))
    return frames


def test_kitti2015_velodyne_frames_and_pooled(shared_data: Path) -> None:
    frames = kitti_frames(shared_data)
    results, pooled = [], np.zeros(12, F)
    for name, gt, predicted, obj in frames:
        # a real hole pattern: every 9th column of the PSMNet map removed, one empty row
        est = predicted.copy()
        est[:, ::9] = 0.0
        est[200] = 0.0
        result = kitti2015_frame(name, gt, None, est, obj)
        counters = devkit_d1_counters(gt, est, obj)
        assert result.counts["occ"] == counters
        assert_same(result.values["occ"], d1_values(counters))
        assert "noc" not in result.values
        results.append(result)
        for i in range(12):
            pooled[i] = F(pooled[i] + F(counters[i]))
    summary = summarize_frames("kitti2015", results)
    assert_same(summary["occ"], d1_values([float(v) for v in pooled]))
    assert summary["occ"]["density"] < 100.0


def test_kitti2015_testbed_sgbm_and_devkit_demo(shared_data: Path) -> None:
    folder = shared_data / "kitti-2015/000005_10"
    gt = read_disparity(folder / "gt_disparity.png")
    est = stereo_estimate(folder / "stereo_left.png", folder / "stereo_right.png", 0.0)
    result = kitti2015_frame("000005_10", gt, None, est, None)
    assert_same(result.values["occ"], d1_values(devkit_d1_counters(gt, est, None), False))
    demo = shared_data / "kitti-2015/devkit_demo"
    gt, est = read_disparity(demo / "disp_gt.png"), read_disparity(demo / "disp_est.png")
    result = kitti2015_frame("demo", gt, None, est, None)
    assert_same(result.values["occ"], d1_values(devkit_d1_counters(gt, est, None), False))
    assert f"{result.values['occ']['D1-all']:.2f}" == "13.62"  # measured


def test_kitti2015_cli_dataset_tree(shared_data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    base = shared_data / VELODYNE
    argv = [
        "--protocol",
        "kitti2015",
        "--scene",
        str(base),
        "--est",
        f"psmnet={base / 'prediction'}",
    ]
    document = run_json(capsys, *argv)
    frames = kitti_frames(shared_data)
    pooled = np.zeros(12, F)
    for (name, gt, est, obj), row in zip(
        frames, document["methods"]["psmnet"]["frames"], strict=True
    ):
        counters = devkit_d1_counters(gt, est, obj)
        assert row["frame"] == name
        assert_same(row["regions"]["occ"], d1_values(counters))
        pooled = (pooled + np.asarray(counters, F)).astype(F)
    assert_same(
        document["methods"]["psmnet"]["summary"]["occ"], d1_values([float(v) for v in pooled])
    )
    assert "noc: no disp_noc_0 ground truth" in document["notes"]
    files = document["provenance"]["inputs"]["files"]
    assert len(files) == 12  # 4 × (GT, obj_map, estimate)
    for path, digest in files.items():
        assert hashlib.sha256(Path(path).read_bytes()).hexdigest() == digest
    protocol = get_protocol("kitti2015")
    assert document["provenance"]["configuration"]["protocol_sha256"] == protocol.sha256()
    # the text report prints the same numbers with two decimals, the devkit's names
    assert main(["eval", *argv]) == 0
    text = capsys.readouterr().out
    summary = document["methods"]["psmnet"]["summary"]["occ"]
    assert f"{summary['D1-all']:.2f} %" in text
    assert "D1-fg (est)" in text
    assert f"{summary['D1-all']:.2f}" == "2.07"  # measured: PSMNet on the four frames


# --------------------------------------------------------------------------- KITTI 2012


def devkit_2012(gt: np.ndarray, est: np.ndarray) -> dict[str, float]:
    ipol = devkit_interpolation(est)
    out_all, out_est = [0] * 4, [0] * 4
    total, total_est = F(0.0), F(0.0)
    n = n_est = 0
    height, width = gt.shape
    for u in range(width):
        for v in range(height):
            if not gt[v, u] > 0:
                continue
            e = F(abs(F(gt[v, u]) - ipol[v, u]))
            has = bool(est[v, u] > 0)
            for i, k in enumerate((2, 3, 4, 5)):
                out_all[i] += bool(e > F(k))
                out_est[i] += bool(e > F(k)) and has
            total = F(total + e)
            n += 1
            if has:
                total_est = F(total_est + e)
                n_est += 1
    values = {f"Out-{k}": ratio32(out_all[i], n) for i, k in enumerate((2, 3, 4, 5))}
    values["Avg"] = float(F(total / max(F(n), F(1))))
    values.update(
        {f"Out-{k} (est)": ratio32(out_est[i], n_est) for i, k in enumerate((2, 3, 4, 5))}
    )
    values["Avg (est)"] = float(F(total_est / max(F(n_est), F(1))))
    values["density"] = ratio32(n_est, n)
    return values


def test_kitti2012_frames_and_stat_mean(shared_data: Path) -> None:
    results, expected = [], []
    for name, gt, predicted, _obj in kitti_frames(shared_data)[:2]:
        est = predicted.copy()
        est[::5, ::3] = 0.0
        result = kitti2012_frame(name, gt, None, est)
        want = devkit_2012(gt, est)
        assert_same(result.values["occ"], want)
        results.append(result)
        expected.append(want)
    summary = summarize_frames("kitti2012", results)
    for column in get_protocol("kitti2012").columns:
        scale = 100.0 if column in get_protocol("kitti2012").percent else 1.0
        acc = F(0.0)
        for row in expected:
            acc = F(acc + F(row[column] / scale))
        assert summary["occ"][column] == scale * float(F(acc / F(len(expected))))


def test_kitti2012_float32_sum_differs_from_exact(shared_data: Path) -> None:
    """The devkit's float32 error sum is not the exact mean: the protocol keeps the float32."""
    _name, gt, est, _obj = kitti_frames(shared_data)[0]
    result = kitti2012_frame("x", gt, None, est)
    valid = gt > 0
    exact = float(np.abs(gt[valid].astype(np.float64) - devkit_interpolation(est)[valid]).mean())
    assert result.values["occ"]["Avg"] != exact
    assert result.values["occ"]["Avg"] == pytest.approx(exact, rel=1e-4)


# ----------------------------------------------------------------------------- MiddEval3


def sdk_evaldisp(gt, est, mask, ndisp) -> dict[str, float]:  # type: ignore[no-untyped-def]
    """evaldisp.cpp with totals counting invalid pixels; rms and A* over the valid errors."""
    n = bad = invalid = 0
    bads = dict.fromkeys((0.5, 1.0, 2.0, 4.0), 0)
    serr, serr2 = F(0.0), F(0.0)
    errors = []
    height, width = gt.shape
    maxd = F(ndisp)
    for y in range(height):
        for x in range(width):
            g = gt[y, x]
            if g == np.inf or (mask is not None and mask[y, x] != 255):
                continue
            d = est[y, x]
            n += 1
            if d == np.inf:
                invalid += 1
                continue
            d = max(F(0.0), min(maxd, d))
            err = F(abs(F(d - g)))
            serr = F(serr + err)
            serr2 = F(serr2 + F(err * err))
            errors.append(err)
            for t in bads:
                bads[t] += bool(err > F(t))
    del bad
    values = {f"bad {t:.1f}": float(F(100.0 * (c + invalid) / n)) for t, c in bads.items()}
    values["invalid"] = float(F(100.0 * invalid / n))
    values["avgErr"] = float(F(serr / F(n - invalid)))
    values["rms"] = float(np.sqrt(F(serr2 / F(n - invalid))))
    ordered = sorted(errors)
    for q in (50, 90, 95, 99):
        values[f"A{q}"] = float(ordered[math.floor(F(F(len(ordered)) * F(q / 100)))])
    return values


def middeval3_estimate(gt: np.ndarray, seed: int, ndisp: float) -> np.ndarray:
    rng = np.random.default_rng(seed)
    est = np.where(np.isfinite(gt), gt, 20.0) + rng.normal(0, 1.5, gt.shape)
    pick = rng.random(gt.shape)
    est[pick < 0.05] = np.inf  # holes
    est[(pick >= 0.05) & (pick < 0.06)] = ndisp + 40  # beyond the range: clipped
    est[(pick >= 0.06) & (pick < 0.07)] = -3.0  # negative: clipped to 0
    return est.astype(F)


@pytest.mark.parametrize("scene", ["Adirondack", "Teddy"])
def test_middeval3_scene_against_sdk(shared_data: Path, scene: str) -> None:
    frame = load_frame(discover(get_protocol("middeval3"), shared_data / MIDDEVAL3 / scene)[0])
    assert frame.ndisp is not None
    assert frame.nonocc_mask is not None
    est = middeval3_estimate(frame.gt, 3, frame.ndisp)
    result = middeval3_frame(scene, frame.gt, est, frame.nonocc_mask, frame.ndisp)
    assert_same(
        result.values["nonocc"], sdk_evaldisp(frame.gt, est, frame.nonocc_mask, frame.ndisp)
    )
    assert_same(result.values["all"], sdk_evaldisp(frame.gt, est, None, frame.ndisp))


def test_middeval3_sgbm_half_size_upsampled(shared_data: Path) -> None:
    """A method run at half size: the SDK upsamples ×2 (values ×2) to the GT."""
    folder = shared_data / MIDDEVAL3 / "Adirondack"
    frame = load_frame(discover(get_protocol("middeval3"), folder)[0])
    full = stereo_estimate(folder / "im0.png", folder / "im1.png", np.inf)
    half = full[::2, ::2] / F(2)
    if half.shape[0] * 2 != frame.gt.shape[0] or half.shape[1] * 2 != frame.gt.shape[1]:
        half = half[: frame.gt.shape[0] // 2, : frame.gt.shape[1] // 2]
        frame_gt = frame.gt[: half.shape[0] * 2, : half.shape[1] * 2]
        mask = frame.nonocc_mask[: half.shape[0] * 2, : half.shape[1] * 2]
    else:
        frame_gt, mask = frame.gt, frame.nonocc_mask
    result = middeval3_frame("a", frame_gt, half, mask, frame.ndisp)
    upsampled = np.repeat(np.repeat(half, 2, 0), 2, 1) * F(2)
    maxdisp = math.ceil(frame.ndisp / 2)  # the half-size ndisp, as MiddEval3's H/Q calib files
    assert_same(result.values["nonocc"], sdk_evaldisp(frame_gt, upsampled, mask, 2 * maxdisp))


def test_middeval3_training_weighted_average(shared_data: Path, tmp_path: Path) -> None:
    """All 15 training scenes in one call, SDK layout (disp0NAME.pfm in each scene folder)."""
    tree = tmp_path / "trainingQ"
    for scene in sorted((shared_data / MIDDEVAL3).iterdir()):
        target = tree / scene.name
        target.mkdir(parents=True)
        for name in ("disp0GT.pfm", "mask0nocc.png", "calib.txt"):
            (target / name).symlink_to(scene / name)
        frame = load_frame(discover(get_protocol("middeval3"), target)[0])
        write_pfm(target / "disp0NOISY.pfm", middeval3_estimate(frame.gt, 7, frame.ndisp or 0))
        write_pfm(target / "disp0GTPLUS.pfm", frame.gt + F(0.75))
    run = evaluate_benchmark("middeval3", tree, {"NOISY": None, "GTPLUS": None})
    assert len(run.frames) == 15
    # The weights of the public source (ITSA eval.py), written out here, not read from the table.
    halved = {"PianoL", "Playroom", "Playtable", "Shelves", "Vintage"}
    weights = [0.5 if name in halved else 1.0 for name in run.frames]
    assert sum(weights) == 12.5
    assert weights == [MIDDEVAL3_WEIGHTS[name] for name in run.frames]
    for method in ("NOISY", "GTPLUS"):
        frames = run.results[method]
        for column in get_protocol("middeval3").columns:
            want = sum(w * f.values["nonocc"][column] for w, f in zip(weights, frames, strict=True))
            assert run.summary[method]["nonocc"][column] == pytest.approx(
                want / sum(weights), rel=1e-12
            )
    assert run.summary["GTPLUS"]["all"]["bad 0.5"] == 100.0
    assert run.summary["GTPLUS"]["all"]["bad 1.0"] == 0.0
    assert run.models is not None
    assert run.models.groups["GTPLUS"] == 1


def test_middeval3_nan_estimates_count_as_invalid(shared_data: Path) -> None:
    """NaN is no estimate, as INF: never a perfect pixel (the SDK's ``d == INFINITY`` misses it)."""
    frame = load_frame(discover(get_protocol("middeval3"), shared_data / MIDDEVAL3 / "Teddy")[0])
    nan = middeval3_frame("a", frame.gt, np.full_like(frame.gt, np.nan), None, frame.ndisp)
    assert nan.values["all"]["invalid"] == 100.0
    assert nan.values["all"]["bad 0.5"] == 100.0
    assert math.isnan(nan.values["all"]["avgErr"])
    estimate = middeval3_estimate(frame.gt, 3, frame.ndisp or 0)
    holes = np.zeros(frame.gt.shape, bool)
    holes[::7, ::5] = True
    with_nan = middeval3_frame("a", frame.gt, np.where(holes, np.nan, estimate), None, frame.ndisp)
    with_inf = middeval3_frame("a", frame.gt, np.where(holes, np.inf, estimate), None, frame.ndisp)
    assert with_nan.values == with_inf.values
    assert with_nan.values["all"]["invalid"] > 0


def test_eth3d_nan_estimates_count_as_missing(shared_data: Path) -> None:
    folder = shared_data / "eth3d-two-view" / "terrace"
    frame = load_frame(discover(get_protocol("eth3d"), folder)[0])
    result = eth3d_frame("a", frame.gt, np.full_like(frame.gt, np.nan), None)
    assert result.values["all"]["coverage"] == 0.0


def test_scene_folder_without_gt_is_refused(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Dropping it would change the weighted average without a word: one line naming it."""
    tree = tmp_path / "trainingQ"
    for scene in ("Adirondack", "Teddy"):
        target = tree / scene
        target.mkdir(parents=True)
        for name in ("disp0GT.pfm", "im0.png", "calib.txt"):
            (target / name).symlink_to(shared_data / MIDDEVAL3 / scene / name)
    (tree / "Teddy" / "disp0GT.pfm").unlink()
    (tree / "results").mkdir()  # not a scene (no im0.png): not in the way
    code = main(["eval", "--protocol", "middeval3", "--scene", str(tree), "--est", "NOISY"])
    err = capsys.readouterr().err
    assert code == 2
    assert f"{tree / 'Teddy'}: a Middlebury MiddEval3 scene folder without disp0GT.pfm" in err
    assert len(err.strip().splitlines()) == 1
    assert [f.name for f in discover(get_protocol("eth3d"), shared_data / "eth3d-two-view")] == [
        "playground",
        "terrace",
    ]


@pytest.mark.parametrize("option", [["--delta", "2"], ["--missing", "ignore"]])
def test_project_options_do_not_apply_to_a_protocol(
    shared_data: Path, capsys: pytest.CaptureFixture[str], option: list[str]
) -> None:
    scene = str(shared_data / MIDDEVAL3 / "Teddy")
    code = main(["eval", "--protocol", "middeval3", "--scene", scene, "--est", "X", *option])
    err = capsys.readouterr().err
    assert code == 2
    assert f"{option[0]} does not apply with --protocol" in err
    assert len(err.strip().splitlines()) == 1


# --------------------------------------------------------------------------------- ETH3D


def eth3d_compute(gt, est, mask) -> dict[str, float]:  # type: ignore[no-untyped-def]
    """main.cc ComputeMetrics, pixel by pixel (double sums of float32 terms)."""
    width = gt.shape[1]
    n_gt = 0
    abs_errors: list[np.float32] = []
    abs_sum = sq_sum = 0.0
    flat_gt, flat_est = gt.ravel(), est.ravel()
    flat_mask = None if mask is None else mask.ravel()
    for i in range(flat_gt.size):
        g, d = flat_gt[i], flat_est[i]
        if not np.isfinite(g) or (flat_mask is not None and flat_mask[i] != 255):
            continue
        n_gt += 1
        if not np.isfinite(d) or d > width or d < -width:
            continue
        error = F(d - g)
        abs_errors.append(F(abs(error)))
        abs_sum += float(abs(error))
        sq_sum += float(F(error * error))
    size = len(abs_errors)
    values = {
        f"bad {t:.1f}": 100.0 * sum(1 for e in abs_errors if e > F(t)) / size
        for t in (0.5, 1.0, 2.0, 4.0)
    }
    values["avgerr"] = abs_sum / size
    values["rms"] = float(np.sqrt(F(sq_sum / size)))
    ordered = sorted(abs_errors)
    for q in (50, 90, 95, 99):
        values[f"A{q}"] = float(ordered[math.floor(F(F(size) * F(q / 100)))])
    values["coverage"] = 100.0 * (1.0 if size == n_gt else size / n_gt)
    return values


@pytest.mark.parametrize("scene", ["playground", "terrace"])
def test_eth3d_sgbm_against_compute_metrics(shared_data: Path, scene: str) -> None:
    folder = shared_data / "eth3d-two-view" / scene
    frame = load_frame(discover(get_protocol("eth3d"), folder)[0])
    est = stereo_estimate(folder / "im0.png", folder / "im1.png", np.inf)
    result = eth3d_frame(scene, frame.gt, est, None)
    assert "nonocc: no mask0nocc.png" in result.notes
    want = eth3d_compute(frame.gt, est, None)
    for column, value in want.items():
        have = result.values["all"][column]
        if column == "avgerr":  # the same double sum; the library's is sequential too
            assert have == pytest.approx(value, rel=1e-15)
        else:
            assert have == value, column
    # a synthetic nonocc mask exercises the masked branch
    mask = np.where(np.arange(frame.gt.size).reshape(frame.gt.shape) % 3, 255, 128).astype(np.uint8)
    masked = eth3d_frame(scene, frame.gt, est, mask)
    assert masked.values["nonocc"]["A90"] == eth3d_compute(frame.gt, est, mask)["A90"]


def test_eth3d_quantile_index_is_float32() -> None:
    """floor(N·0.99f) in float32 differs from the exact floor for some N: ETH3D's is kept."""
    n = 229401  # the first N where they differ (measured): 229401 × 0.99 = 227106.99
    assert (n * 99) // 100 == 227106
    assert quantile_index(n, 0.99) == 227107
    errors = np.arange(n, dtype=F).reshape(1, n)
    result = eth3d_frame("x", np.zeros((1, n), F), errors, None)
    assert result.values["all"]["A99"] == 227107.0


# ------------------------------------------------------------------------------- errors


def test_missing_result_is_one_line(
    shared_data: Path, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    code = main(
        [
            "eval",
            "--protocol",
            "kitti2015",
            "--scene",
            str(shared_data / VELODYNE),
            "--est",
            f"m={tmp_path}",
        ]
    )
    err = capsys.readouterr().err
    assert code == 2
    assert "no result of method 'm' for frame 000010" in err
    assert len(err.strip().splitlines()) == 1


def test_found_estimates_follow_benchmark_layouts(shared_data: Path) -> None:
    frames = discover(get_protocol("kitti2015"), shared_data / VELODYNE)
    assert [f.name for f in frames] == ["000010", "000043", "000112", "000150"]
    assert all(f.obj_map is not None and f.gt_noc is None for f in frames)
    kitti2015 = get_protocol("kitti2015")
    found = find_estimate(kitti2015, frames[0], "psm", shared_data / VELODYNE / "prediction")
    assert found.name == "000010.png"
    assert read_estimate(found).dtype == np.float32


def test_single_frame_files_on_the_command_line(
    shared_data: Path, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """--gt FILE with the protocol's side files: the same numbers as the dataset-tree path."""
    scene = shared_data / MIDDEVAL3 / "Teddy"
    frame = load_frame(discover(get_protocol("middeval3"), scene)[0])
    est = middeval3_estimate(frame.gt, 5, frame.ndisp or 0)
    write_pfm(tmp_path / "mine.pfm", est)
    document = run_json(
        capsys,
        *("--protocol", "middeval3", "--gt", str(scene / "disp0GT.pfm")),
        *("--mask", f"nonocc={scene / 'mask0nocc.png'}", "--calib", str(scene / "calib.txt")),
        *("--est", f"mine={tmp_path / 'mine.pfm'}"),
    )
    values = document["methods"]["mine"]["frames"][0]["regions"]
    assert_same(values["nonocc"], sdk_evaldisp(frame.gt, est, frame.nonocc_mask, frame.ndisp))
    base = shared_data / VELODYNE
    _name, gt, predicted, obj = kitti_frames(shared_data)[1]
    document = run_json(
        capsys,
        *("--protocol", "kitti2015", "--gt", str(base / "gt/disp_occ_0/000043.png")),
        *("--obj-map", str(base / "gt/obj_map/000043.png")),
        *("--est", f"psm={base / 'prediction/000043.png'}"),
    )
    row = document["methods"]["psm"]["frames"][0]["regions"]["occ"]
    assert_same(row, d1_values(devkit_d1_counters(gt, predicted, obj)))


def test_kitti2012_metrics_on_a_kitti2015_tree(
    shared_data: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = shared_data / VELODYNE
    argv = ["--protocol", "kitti2012", "--scene", str(base), "--est", f"psm={base / 'prediction'}"]
    document = run_json(capsys, *argv)
    assert document["frames"] == ["000010", "000043", "000112", "000150"]
    _name, gt, predicted, _obj = kitti_frames(shared_data)[0]
    want = devkit_2012(gt, predicted)
    assert_same(document["methods"]["psm"]["frames"][0]["regions"]["occ"], want)
    assert main(["eval", *argv, "--summary-only"]) == 0
    text = capsys.readouterr().out
    assert "summary, region occ" in text
    assert "Out-3 (est)" in text
    assert "method psm: per frame" not in text


def test_moved_digits_are_reported(tmp_path: Path) -> None:
    """Where float32 changes a printed value the run lists it with the exact value beside it."""
    gt = np.full((6, 8), 100.0, F)
    estimate = np.full((6, 8), 95.0, F)  # e/d = 5 % exactly: an outlier only in float32
    write_disparity_png16(tmp_path / "gt.png", gt)
    write_disparity_png16(tmp_path / "est.png", estimate)
    frame = single_frame(tmp_path / "gt.png")
    run = evaluate_frames("kitti2015", [frame], {"m": tmp_path / "est.png"}, "x")
    moved = {(m.frame, m.column): (m.official, m.exact) for m in run.moved}
    assert moved[("gt", "D1-all")] == (100.0, 0.0)
    assert moved[("summary", "D1-all")] == (100.0, 0.0)
    assert run.to_dict()["float32_moved_digits"][0]["official"] == 100.0


def test_float32_moves_middeval3_digits_on_real_scenes(shared_data: Path) -> None:
    """On MiddEval3 Q the SDK's float32 error sum changes printed avgErr/rms digits (measured)."""
    folder = shared_data / MIDDEVAL3 / "PianoL"
    frame = load_frame(discover(get_protocol("middeval3"), folder)[0])
    est = stereo_estimate(folder / "im0.png", folder / "im1.png", np.inf)
    result = evaluate_frame("middeval3", frame, est)
    assert result.exact is not None
    official, exact = result.values["all"]["avgErr"], result.exact.values["all"]["avgErr"]
    assert official != exact
    assert official == sdk_evaldisp(frame.gt, est, None, frame.ndisp)["avgErr"]
    assert exact == pytest.approx(official, rel=1e-3)


def test_results_must_be_in_the_tools_format(
    shared_data: Path, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """KITTI reads 16-bit PNG, MiddEval3/ETH3D PFM: anything else is a one-line error."""
    base = shared_data / VELODYNE
    write_pfm(tmp_path / "000043.pfm", read_disparity(base / "prediction/000043.png"))
    argv = ["eval", "--protocol", "kitti2015", "--gt", str(base / "gt/disp_occ_0/000043.png")]
    assert main([*argv, "--est", f"m={tmp_path / '000043.pfm'}"]) == 2
    assert "must be 1-channel 16-bit PNG" in capsys.readouterr().err
    scene = shared_data / MIDDEVAL3 / "Teddy"
    png = tmp_path / "teddy.png"
    cv2.imwrite(str(png), np.zeros((4, 4), np.uint8))
    assert (
        main(["eval", "--protocol", "middeval3", "--scene", str(scene), "--est", f"m={png}"]) == 2
    )
    assert "must be PFM (INF = no estimate)" in capsys.readouterr().err
