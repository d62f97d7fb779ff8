"""``eval --scene`` of a folder with several frames: each estimate against its own frame.

On the kitti-lidar KITTI 2015 folder (four frames, each with its official GT map and its
Velodyne scan) an estimate of frame 000043 used to be scored against frame 000010's scan.
The numbers here are re-computed with plain numpy from the files (official GT), or compared
with ``eval`` of a folder holding that one frame only (scan).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from dispeval_ros.cli.main import main

FOLDER = "kitti-lidar/kitti2015-with-velodyne"
FRAMES = ("000010", "000043", "000112", "000150")
QUICK = ("--criteria", "all", "--measures", "bmp", "d1")


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(["eval", *argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def kitti_png(path: Path) -> np.ndarray:
    """A KITTI uint16 disparity PNG in px (value / 256; 0 = none), read by OpenCV."""
    raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert raw is not None
    assert raw.dtype == np.uint16
    return raw.astype(np.float64) / 256.0


def numpy_bmp_d1(gt_file: Path, est_file: Path) -> tuple[float, float, int]:
    """BMP (|e| > 1 px) and D1 (|e| > 3 px and > 5 % of the GT), in %, over the valid GT."""
    gt, est = kitti_png(gt_file), kitti_png(est_file)
    valid = gt > 0
    assert (est[valid] > 0).all()  # a dense estimate: no missing-estimate policy involved
    error = np.abs(est[valid] - gt[valid])
    bmp = 100.0 * np.count_nonzero(error > 1.0) / error.size
    d1 = 100.0 * np.count_nonzero((error > 3.0) & (error > 0.05 * gt[valid])) / error.size
    return bmp, d1, int(error.size)


@pytest.fixture
def kitti(shared_data: Path) -> Path:
    return shared_data / FOLDER


def all_scores(document: dict) -> tuple[float, float, int]:
    scores = document["frames"][0]["criteria"]["all"]
    return scores["bmp"], scores["d1"], scores["n"]


def test_estimate_of_a_frame_is_scored_against_that_frames_official_map(
    capsys: pytest.CaptureFixture[str], kitti: Path
) -> None:
    estimate = kitti / "prediction" / "000043.png"
    code, out, _ = run(
        capsys, "--scene", str(kitti), "--est", f"psmnet={estimate}", *QUICK, "--json"
    )
    assert code == 0
    document = json.loads(out)
    assert (document["frame"], document["gt_source"]) == ("000043", "official")
    assert document["frames"][0]["frame"] == "000043"
    bmp, d1, n = numpy_bmp_d1(kitti / "gt" / "disp_occ_0" / "000043.png", estimate)
    assert all_scores(document) == (pytest.approx(bmp, abs=1e-9), pytest.approx(d1, abs=1e-9), n)
    record = document["provenance"]
    assert record["configuration"]["frames"] == [{"frame": "000043", "gt_source": "official"}]
    assert str(kitti / "gt" / "disp_occ_0" / "000043.png") in record["inputs"]["files"]
    code, out, _ = run(capsys, "--scene", str(kitti), "--est", f"psmnet={estimate}", *QUICK)
    assert code == 0
    assert "frame 000043: official GT map gt/disp_occ_0/000043.png" in out


def test_scan_source_equals_eval_of_the_single_frame(
    capsys: pytest.CaptureFixture[str], kitti: Path, shared_data: Path, tmp_path: Path
) -> None:
    estimate = kitti / "prediction" / "000043.png"
    argv = ["--est", f"psmnet={estimate}", *QUICK, "--json"]
    code, out, _ = run(capsys, "--scene", str(kitti), "--gt-source", "scan", *argv)
    assert code == 0
    document = json.loads(out)
    assert (document["frame"], document["gt_source"]) == ("000043", "scan")
    files = document["provenance"]["inputs"]["files"]
    assert str(kitti / "velodyne_points" / "000043.bin") in files
    assert not any("disp_occ_0" in name for name in files)
    # The same frame alone in a folder of its own (with the day's calibration in it).
    single = tmp_path / "one"
    for sub, suffix in (("image_02", ".png"), ("image_03", ".png"), ("velodyne_points", ".bin")):
        (single / sub).mkdir(parents=True)
        shutil.copy(kitti / sub / f"000043{suffix}", single / sub)
    for calib in (shared_data / "kitti-lidar" / "raw-calib-2011_09_26").iterdir():
        shutil.copy(calib, single)
    code, out, _ = run(capsys, "--scene", str(single), *argv)
    assert code == 0
    alone = json.loads(out)
    assert all_scores(document) == all_scores(alone)
    bmp, d1, n = all_scores(document)
    assert (round(bmp, 2), round(d1, 2)) == (9.35, 0.96)  # the numbers for 000043
    code, out, _ = run(capsys, "--scene", str(kitti), "--gt-source", "scan", *argv[:-1])
    assert code == 0
    assert "frame 000043: projected LiDAR scan velodyne_points/000043.bin" in out
    assert f"({n} valid points)" in out.replace("1242×375, ", "")


def test_folder_of_estimates_scores_every_frame(
    capsys: pytest.CaptureFixture[str], kitti: Path
) -> None:
    predictions = kitti / "prediction"
    code, out, _ = run(
        capsys, "--scene", str(kitti), "--est", f"psmnet={predictions}", *QUICK, "--json"
    )
    assert code == 0
    document = json.loads(out)
    assert [d["frame"] for d in document["per_frame"]] == list(FRAMES)
    assert [(f["frame"], f["method"]) for f in document["frames"]] == [
        (frame, "psmnet") for frame in FRAMES
    ]
    for frame, part in zip(FRAMES, document["per_frame"], strict=True):
        expected = numpy_bmp_d1(
            kitti / "gt" / "disp_occ_0" / f"{frame}.png", predictions / f"{frame}.png"
        )
        assert all_scores(part) == pytest.approx(expected, abs=1e-9)
        assert part["gt_source"] == "official"
    configured = document["provenance"]["configuration"]["frames"]
    assert [f["frame"] for f in configured] == list(FRAMES)


def test_frame_option_scores_only_that_frame(
    capsys: pytest.CaptureFixture[str], kitti: Path
) -> None:
    predictions = kitti / "prediction"
    code, out, _ = run(
        capsys, "--scene", str(kitti), "--frame", "000112", "--est", f"psmnet={predictions}",
        *QUICK, "--json",
    )  # fmt: skip
    assert code == 0
    document = json.loads(out)
    assert document["frame"] == "000112"
    expected = numpy_bmp_d1(kitti / "gt" / "disp_occ_0" / "000112.png", predictions / "000112.png")
    assert all_scores(document) == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (lambda k, d: ["--scene", k, "--frame", "000044", "--est", f"p={k}/prediction"],
         "--frame 000044: no such frame; the frames of {k}: 000010, 000043, 000112, 000150"),
        (lambda k, d: ["--scene", k, "--frame", "000010", "--est", f"p={k}/prediction/000043.png"],
         "is named for frame 000043, but --frame 000010"),
        (lambda k, d: ["--scene", k, "--est", f"p={k}/gt"],
         "no estimate of frame(s) 000010, 000043, 000112, 000150"),
        (lambda k, d: ["--scene", k, "--est", f"p={d}/kitti-2015/devkit_demo/disp_est.png"],
         "'disp_est' is not a frame; the frames of {k}: 000010, 000043, 000112, 000150"),
        (lambda k, d: ["--scene", f"{d}/kitti-lidar/stereo-rcnn-demo", "--gt-source", "official",
                       "--est", f"p={k}/prediction/000043.png"],
         "--gt-source official: frame stereo-rcnn-demo"),
        (lambda k, d: ["--scene", f"{d}/middlebury-2001-2003/teddy", "--gt-source", "scan",
                       "--est", f"p={d}/middlebury-2001-2003/teddy/groundtruth_right.png"],
         "--gt-source scan: frame teddy"),
        (lambda k, d: ["--gt", f"{k}/gt/disp_occ_0/000043.png", "--frame", "000043",
                       "--est", f"p={k}/prediction/000043.png"],
         "--frame chooses among the frames of a scene folder"),
        (lambda k, d: ["--scene", k, "--est", f"p={k}/prediction",
                       "--mask", f"nonocc={k}/gt/obj_map/000043.png"],
         "--mask is for one frame, but 4 frames are scored"),
    ],
)  # fmt: skip
def test_wrong_frame_or_source_is_one_line(
    capsys: pytest.CaptureFixture[str], shared_data: Path, argv, expected: str
) -> None:
    kitti = str(shared_data / FOLDER)
    code, out, err = run(capsys, *argv(kitti, str(shared_data)), *QUICK)
    assert (code, out) == (2, "")
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert expected.format(k=kitti) in err
