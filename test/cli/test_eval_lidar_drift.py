"""``eval --scene DRIVE --egomotion``: the LiDAR drift between scans on the shared KITTI raw drive.

The CLI's sums are checked against a plain numpy re-computation written from the definition
(docs/method.md, "LiDAR drift between scans"), on inputs read here: the scans projected by
numpy (points behind the camera and outside the image dropped, the nearest point of a pixel
kept, the 7×7 / 10 % parallax filter), the calibration by the egomotion tests' independent
reader, the motion as the CLI gets it (the oxts poses at the left images' stamps, checked
against a hand interpolation there), the estimates under each missing-estimate policy by
``reference.scored_estimate``. The shared drive's first image is before its first oxts sample,
so frame 0's pairs are problems and are not scored.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import test_eval_egomotion as ego
from drift_support import GAP, THRESHOLDS, WINDOW, numpy_drift
from test_eval_egomotion import DRIVE, METHODS, cli_motion, est_args, geometry, run

drive = ego.drive  # the fixtures: the drive and its SGBM and BM maps
estimates = ego.estimates

pytestmark = pytest.mark.data

QUICK = ("--criteria", "all", "depth", "--measures", "mae", "--gt-free-criteria", "all")


def numpy_scan(drive: Path, frame: str) -> tuple[np.ndarray, dict[str, int]]:
    """The scan projected into the left camera (disparity, 0 where no point) and its counts."""
    velo_to_camera, _, camera = geometry(drive)
    points = np.fromfile(drive / "velodyne_points" / "data" / f"{frame}.bin", "<f4")
    xyz = points.reshape(-1, 4)[:, :3].astype(np.float64)
    xyz = xyz @ velo_to_camera[:3, :3].T + velo_to_camera[:3, 3]
    f, cx, cy = camera.camera.f, camera.cx, camera.cy
    front = xyz[:, 2] > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.floor(f * xyz[:, 0] / xyz[:, 2] + cx + 0.5)
        v = np.floor(f * xyz[:, 1] / xyz[:, 2] + cy + 0.5)
    height, width = 375, 1242
    inside = front & (u >= 0) & (u < width) & (v >= 0) & (v < height)
    depth = np.full((height, width), np.inf, np.float32)
    np.minimum.at(depth, (v[inside].astype(int), u[inside].astype(int)), xyz[inside, 2])
    padded = np.pad(depth, WINDOW // 2, constant_values=np.inf)
    windows = np.lib.stride_tricks.sliding_window_view(padded, (WINDOW, WINDOW))
    nearest = windows.min(axis=(2, 3))
    kept = np.isfinite(depth) & ~(nearest < (depth / np.float32(1 + GAP)).astype(np.float32))
    scan = np.zeros((height, width), np.float32)
    scan[kept] = camera.camera.fb / depth[kept].astype(np.float64)
    counts = {"behind": int((~front).sum()), "outside": int((front & ~inside).sum())}
    return scan, counts


def frames_of(drive: Path) -> list[str]:
    return sorted(p.stem for p in (drive / "image_02" / "data").glob("*.png"))


def expected_sums(
    drive: Path, estimates: dict[str, Path], method: str, policy: str, step: int
) -> np.ndarray:
    """The numpy sums of one method over every pair ``t → t + step`` of the drive."""
    _, _, camera = geometry(drive)
    frames = frames_of(drive)
    scans = [numpy_scan(drive, frame)[0] for frame in frames]
    maps = [np.load(estimates[method] / f"{frame}.npy") for frame in frames]
    motions = {t: cli_motion(drive, t, t + step) for t in range(1, len(frames) - step)}
    pairs = [
        numpy_drift((scans[t], scans[t + step]), (maps[t], maps[t + step]), motion, camera, policy)
        for t, motion in motions.items()
    ]
    return np.sum(pairs, axis=0)


def drift_json(capsys, drive: Path, estimates: dict[str, Path], *extra: str) -> dict:
    code, out, err = run(
        capsys, "--scene", str(drive), *est_args(estimates), *QUICK, "--egomotion", "--json",
        *extra,
    )  # fmt: skip
    assert code == 0, err
    return json.loads(out)["egomotion"]["lidar_drift"]


def test_the_numpy_scans_are_the_ground_truth_eval_scores(drive: Path) -> None:
    """The README's traps: half a scan is behind the camera, most of the rest outside the
    image, and the points cover the rows from about 106 down."""
    from dispeval_ros.io.scenes import list_frames

    scenes = list_frames(drive)
    for frame, scene in zip(frames_of(drive), scenes, strict=True):
        scan, counts = numpy_scan(drive, frame)
        np.testing.assert_array_equal(scan, scene.gt)
        assert counts["behind"] > 55_000  # of about 115 000 points
        assert counts["outside"] > 30_000
        rows = np.flatnonzero((scan > 0).any(axis=1))
        assert 100 <= rows[0] <= 120  # 106–120 after the parallax filter
        assert rows[-1] == 374


@pytest.mark.parametrize(("policy", "step"), [
    ("interpolate", 1), ("thesis", 1), ("ignore", 1), ("ignore", 9),
])  # fmt: skip
def test_the_sums_equal_a_numpy_recomputation(
    capsys: pytest.CaptureFixture[str],
    drive: Path,
    estimates: dict[str, Path],
    policy: str,
    step: int,
) -> None:
    got = drift_json(capsys, drive, estimates, "--missing", policy, "--egomotion-step", str(step))
    assert got["options"] == {"missing": policy, "visibility": "7,0.1", "thresholds": [*THRESHOLDS]}
    for method in METHODS:
        sums = got["methods"][method]["sums"]
        assert next(iter(sums)) == "drift:all"
        assert len(sums) == 4
        table = np.array([list(one.values()) for one in sums.values()])
        expected = expected_sums(drive, estimates, method, policy, step)
        counts = [0, 1, 2, 3, 4, 5, 6, *range(11, 11 + len(THRESHOLDS))]
        np.testing.assert_array_equal(table[:, counts], expected[:, counts])
        np.testing.assert_allclose(table[:, 7:11], expected[:, 7:11], rtol=1e-9, atol=1e-9)
        one = got["methods"][method]["criteria"]["drift:all"]
        n = one["n_drift"]
        assert one["mean"] == pytest.approx(sums["drift:all"]["sum_abs"] / n)
        assert one["counted"] == pytest.approx(100 * n / one["n"])
        if policy != "ignore":
            assert one["n_missing"] == one["n_missing_target"] == 0
        if step == 9:  # 7 m forward: the nearest ground is behind the camera
            drops = ("n_behind", "n_outside", "n_hidden", "n_missing", "n_missing_target")
            assert all(one[d] > 100 for d in drops), one


def test_moving_the_scan_by_the_motion_beats_its_inverse_and_no_motion(
    drive: Path, estimates: dict[str, Path]
) -> None:
    """The convention, as docs/method.md quotes it: 0.45–0.6 of either alternative."""
    from dispeval_ros.core.lidar_drift import DriftOptions, coded_estimate, lidar_drift

    _, _, camera = geometry(drive)
    frames = frames_of(drive)
    options = DriftOptions(missing="ignore")
    for t in (1, 3, 6, 9):
        scans = [numpy_scan(drive, frames[i])[0] for i in (t, t + 1)]
        maps = [coded_estimate(np.load(estimates["sgbm"] / f"{frames[i]}.npy"), "ignore")
                for i in (t, t + 1)]  # fmt: skip
        motion = cli_motion(drive, t, t + 1)
        mean = {
            name: lidar_drift(*scans, *maps, moved, camera, options=options).summary("all")["mean"]
            for name, moved in (("right", motion), ("inverse", np.linalg.inv(motion)),
                                ("none", np.eye(4)))
        }  # fmt: skip
        assert 0.4 < mean["right"] / min(mean["inverse"], mean["none"]) < 0.65, mean


def test_the_text_table_is_labelled_and_shows_the_json_values(
    capsys: pytest.CaptureFixture[str], drive: Path, estimates: dict[str, Path]
) -> None:
    argv = ("--scene", str(drive), *est_args(estimates), *QUICK, "--egomotion")
    code, out, err = run(capsys, *argv)
    assert code == 0, err
    drift = json.loads(run(capsys, *argv, "--json")[1])["egomotion"]["lidar_drift"]
    assert drift["label"].startswith("temporal noise against the LiDAR scans")
    assert "not accuracy" in drift["label"]
    text = out[out.index("LiDAR drift between scans") :]
    assert "not accuracy" in " ".join(text.split())
    columns = ["n", "counted", "mean", "rms", *(f"bad_{t:g}" for t in THRESHOLDS),
               "bias_drift", "n_behind", "n_outside", "n_hidden", "n_missing",
               "n_missing_target"]  # fmt: skip
    for method in METHODS:
        values = drift["methods"][method]["criteria"]["drift:all"]
        parts = [line.split()[2:] for line in text.splitlines()
                 if re.match(rf"drift:all\s+{method}\s", line)]  # fmt: skip
        cells = [cell for part in parts for cell in part]
        assert len(cells) == len(columns)
        for cell, column in zip(cells, columns, strict=True):
            if column.startswith("n"):
                assert int(cell) == values[column], column
            else:
                assert float(cell) == pytest.approx(values[column], rel=1e-3), column
    rows = [
        line.split()[0] for line in text.splitlines() if re.match(r"\S+\s+(sgbm|bm_fast)\s", line)
    ]
    assert rows
    assert all(row.startswith("drift:") for row in rows)


def test_without_egomotion_there_is_no_drift(
    capsys: pytest.CaptureFixture[str], drive: Path, estimates: dict[str, Path]
) -> None:
    code, out, _ = run(capsys, "--scene", str(drive), *est_args(estimates), *QUICK, "--json")
    assert code == 0
    assert "lidar_drift" not in out
    assert DRIVE.endswith(drive.name)


def test_the_readme_states_the_drift_numbers(
    capsys: pytest.CaptureFixture[str], shared_data: Path, drive: Path, tmp_path: Path
) -> None:
    """The README's drift sentences, on the maps its example writes (its table is checked by
    test_eval_egomotion's README test)."""
    from test_readme import README

    code = ego.readme_example()[0]
    (tmp_path / "kitti-raw-drive-0048").symlink_to(shared_data / "kitti-raw-drive-0048")
    environment = {"PYTHONPATH": str(ego.CLONE), "PATH": "/usr/bin:/bin"}
    subprocess.run([sys.executable, "-c", code], cwd=tmp_path, check=True, env=environment)
    estimates = {name: tmp_path / name for name in METHODS}
    text = README.read_text(encoding="utf-8")
    text = " ".join(text[text.index("<!-- /egomotion-example -->") :].split())
    runs = {
        p: drift_json(capsys, drive, estimates, "--missing", p) for p in ("interpolate", "ignore")
    }
    values = {
        policy: {m: run["methods"][m]["criteria"] for m in METHODS} for policy, run in runs.items()
    }
    sgbm, bm = (values["interpolate"][m]["drift:all"] for m in METHODS)
    assert sgbm["n_drift"] == bm["n_drift"]
    assert f"{int(sgbm['n_drift'])} of the {int(sgbm['n'])} points counted for both methods" in text
    assert sgbm["n"] == sgbm["n_drift"] + sgbm["n_outside"] + sgbm["n_hidden"]
    ignored = [values["ignore"][m]["drift:all"] for m in METHODS]
    assert (
        f"(SGBM {ignored[0]['mean']:.2f} px over {ignored[0]['counted']:.1f} % of the points, "
        f"BM {ignored[1]['mean']:.2f} px over {ignored[1]['counted']:.1f} %)" in text
    )
    near, mid, far = (values["interpolate"]["sgbm"][f"drift:{c}"]["mean"]
                      for c in ("0-10m", "10-30m", "30+m"))  # fmt: skip
    assert f"SGBM drifts {near:.2f} px below 10 m, {mid:.2f} px at 10–30 m, {far:.2f} px" in text
    assert sgbm["mean"] < bm["mean"]
