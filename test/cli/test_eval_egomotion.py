"""``eval --scene DRIVE --egomotion``: the ego-motion residual on the shared KITTI raw drive.

The CLI's sums are checked against :func:`~dispeval_ros.core.egomotion.egomotion_residual`
called here on inputs read here: the motion from the oxts files by the devkit's
``convertOxtsToPose`` and the calibration files (``T_cam_imu = shift·R_rect_00·[R|T]_velo ·
[R|T]_imu``), interpolated here at the left images' stamps as tf2 does (translation linearly,
rotation by slerp, the oxts unit's pose, then the camera's mount), the images by OpenCV, the
estimates by numpy. The motion's convention is checked by geometry alone: the scan of frame t
moved by it lands on the scan of frame t + 1.
"""

from __future__ import annotations

import contextlib
import json
import math
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from test_readme import README, readme_block

from dispeval_ros.cli.main import main
from dispeval_ros.core.camera import Camera
from dispeval_ros.core.egomotion import (
    EgoMotionOptions,
    PinholeCamera,
    egomotion_residual,
    prepare_frame,
)
from dispeval_ros.errors import ExtrapolationError
from dispeval_ros.io.kitti_raw import drive_motion, open_drive
from dispeval_ros.offline.make_bag import BASE_FRAME, CAMERA_FRAME, ODOM_FRAME
from dispeval_ros.testbed import default_methods

pytestmark = pytest.mark.data

DRIVE = "kitti-raw-drive-0048/2011_09_26/2011_09_26_drive_0048_sync"
METHODS = ("sgbm", "bm_fast")
QUICK = ("--criteria", "all", "--measures", "mae", "--gt-free-criteria", "all")


@pytest.fixture(scope="module")
def drive(shared_data: Path) -> Path:
    return shared_data / DRIVE


@pytest.fixture(scope="module")
def estimates(drive: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The testbed's SGBM and BM maps of every frame, ``NAME/FRAME.npy``."""
    root = tmp_path_factory.mktemp("estimates")
    methods = [m for m in default_methods(1242) if m.name in METHODS]
    for left in sorted((drive / "image_02" / "data").glob("*.png")):
        grey = [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in (left, _right(left))]
        for method in methods:
            (root / method.name).mkdir(exist_ok=True)
            np.save(root / method.name / f"{left.stem}.npy", method.compute(*grey))
    return {name: root / name for name in METHODS}


def _right(left: Path) -> Path:
    return left.parents[2] / "image_03" / "data" / left.name


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(["eval", *argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def est_args(estimates: dict[str, Path]) -> list[str]:
    return [arg for name, path in estimates.items() for arg in ("--est", f"{name}={path}")]


# -- independent readers of the drive ---------------------------------------------------------


def _calib(file: Path) -> dict[str, np.ndarray]:
    fields = {}
    for line in file.read_text().splitlines():
        key, _, values = line.partition(":")
        with contextlib.suppress(ValueError):  # calib_time
            fields[key] = np.array(values.split(), dtype=float)
    return fields


def grey(file: Path) -> np.ndarray:
    """The left image in grey by BT.601 (cvtColor; IMREAD_GRAYSCALE rounds otherwise)."""
    return cv2.cvtColor(cv2.imread(str(file), cv2.IMREAD_COLOR), cv2.COLOR_BGR2GRAY)


def _rigid(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = rotation.reshape(3, 3), translation
    return matrix


def geometry(drive: Path) -> tuple[np.ndarray, np.ndarray, PinholeCamera]:
    """LiDAR → left rectified camera (K·[I|0] projects it), IMU → that camera, the camera."""
    cam = _calib(drive.parent / "calib_cam_to_cam.txt")
    velo = _calib(drive.parent / "calib_velo_to_cam.txt")
    imu = _calib(drive.parent / "calib_imu_to_velo.txt")
    p2, p3 = cam["P_rect_02"].reshape(3, 4), cam["P_rect_03"].reshape(3, 4)
    shift = _rigid(np.eye(3), np.linalg.solve(p2[:, :3], p2[:, 3]))
    velo_to_camera = shift @ _rigid(cam["R_rect_00"], np.zeros(3)) @ _rigid(velo["R"], velo["T"])
    imu_to_camera = velo_to_camera @ _rigid(imu["R"], imu["T"])
    f = p2[0, 0]
    camera = PinholeCamera(Camera(f, (p2[0, 3] - p3[0, 3]) / f, 0.0), p2[0, 2], p2[1, 2])
    return velo_to_camera, imu_to_camera, camera


def oxts_unit_poses(drive: Path) -> list[np.ndarray]:
    """The devkit's ``convertOxtsToPose``: the oxts unit's pose at each sample, the first I."""
    rows = np.array([np.loadtxt(f)[:6] for f in sorted((drive / "oxts" / "data").glob("*.txt"))])
    lat, lon, alt, roll, pitch, yaw = rows.T
    scale, er = math.cos(math.radians(lat[0])), 6378137.0
    poses = []
    for i in range(len(rows)):
        c, s = np.cos([roll[i], pitch[i], yaw[i]]), np.sin([roll[i], pitch[i], yaw[i]])
        rx = np.array([[1, 0, 0], [0, c[0], -s[0]], [0, s[0], c[0]]])
        ry = np.array([[c[1], 0, s[1]], [0, 1, 0], [-s[1], 0, c[1]]])
        rz = np.array([[c[2], -s[2], 0], [s[2], c[2], 0], [0, 0, 1]])
        t = (scale * lon[i] * math.pi * er / 180,
             scale * er * math.log(math.tan(math.pi * (90 + lat[i]) / 360)), alt[i])  # fmt: skip
        poses.append(_rigid(rz @ ry @ rx, np.array(t)))
    return [np.linalg.inv(poses[0]) @ pose for pose in poses]


def stamps_ns(drive: Path, stream: str) -> np.ndarray:
    """A stream's ``timestamps.txt`` in integer ns (numpy's datetime64 keeps all 9 digits)."""
    lines = (drive / stream / "timestamps.txt").read_text().split()
    text = [f"{day}T{time}" for day, time in zip(lines[::2], lines[1::2], strict=True)]
    return np.array(text, dtype="datetime64[ns]").astype(np.int64)


def _quaternion(rotation: np.ndarray) -> np.ndarray:
    """``(w, x, y, z)`` of a rotation matrix (its largest component first, for precision)."""
    r = rotation
    candidates = np.array([
        [1 + r[0, 0] + r[1, 1] + r[2, 2], r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]],
        [r[2, 1] - r[1, 2], 1 + r[0, 0] - r[1, 1] - r[2, 2], r[0, 1] + r[1, 0], r[0, 2] + r[2, 0]],
        [r[0, 2] - r[2, 0], r[0, 1] + r[1, 0], 1 - r[0, 0] + r[1, 1] - r[2, 2], r[1, 2] + r[2, 1]],
        [r[1, 0] - r[0, 1], r[0, 2] + r[2, 0], r[1, 2] + r[2, 1], 1 - r[0, 0] - r[1, 1] + r[2, 2]],
    ])  # fmt: skip
    best = int(np.argmax(np.diag(candidates)))
    q = candidates[best]
    return q / np.linalg.norm(q)


def _rotation_of(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])  # fmt: skip


def interpolated(poses: list[np.ndarray], stamps: np.ndarray, stamp: int) -> np.ndarray | None:
    """The pose at ``stamp`` between the two samples around it (None outside them).

    tf2's rule from its definition: the translation linearly, the rotation by slerp on the
    shorter arc, at the fraction of the time between the two samples.
    """
    after = int(np.searchsorted(stamps, stamp))
    if after < len(stamps) and stamps[after] == stamp:
        return poses[after]
    if after in (0, len(stamps)):
        return None
    a, b = poses[after - 1], poses[after]
    ratio = (stamp - stamps[after - 1]) / (stamps[after] - stamps[after - 1])
    q0, q1 = _quaternion(a[:3, :3]), _quaternion(b[:3, :3])
    if q0 @ q1 < 0:
        q1 = -q1
    angle = math.acos(min(1.0, float(q0 @ q1)))
    q = (math.sin((1 - ratio) * angle) * q0 + math.sin(ratio * angle) * q1) / math.sin(angle)
    return _rigid(_rotation_of(q), a[:3, 3] + ratio * (b[:3, 3] - a[:3, 3]))


def image_motions(drive: Path, step: int = 1) -> dict[int, np.ndarray]:
    """Pose of the camera at frame t + step in the camera at frame t, by frame t.

    The oxts unit's poses interpolated at the left images' stamps, then carried to the camera
    by its mount; the frames whose image stamp lies outside the oxts samples have none.
    """
    _, imu_to_camera, _ = geometry(drive)
    unit, oxts = oxts_unit_poses(drive), stamps_ns(drive, "oxts")
    camera = [interpolated(unit, oxts, int(s)) for s in stamps_ns(drive, "image_02")]
    poses = [None if p is None else p @ np.linalg.inv(imu_to_camera) for p in camera]
    return {
        t: np.linalg.inv(a) @ b
        for t, (a, b) in enumerate(zip(poses, poses[step:], strict=False))
        if a is not None and b is not None
    }


def cli_motion(drive: Path, first: int, second: int) -> np.ndarray:
    """The motion ``eval --egomotion`` gives the core for a pair of frames."""
    motion = drive_motion(open_drive(drive), fixed=ODOM_FRAME, base=BASE_FRAME, camera=CAMERA_FRAME)
    return motion.between(first, second)


OUTSIDE = (
    "no pair 0000000000 → 0000000001 (sgbm, bm_fast): frame 0000000000's left image (the oxts "
    "poses as /tf): /tf odom → base_link has no sample around 1317046450.911916288 s: the stamp "
    "is before its oldest sample (1317046450.924614488 s) by 12.698 ms; 11 sample(s) span "
    "1317046450.924614488 s – 1317046451.954821582 s and a transform is never extrapolated"
)
"""The shared drive's first image is 12.7 ms before its first oxts sample: its pairs' line."""


# -- the tests ---------------------------------------------------------------------------------


@pytest.mark.parametrize("step", [1, 3])
def test_the_sums_equal_the_core_on_the_same_inputs(
    capsys: pytest.CaptureFixture[str], drive: Path, estimates: dict[str, Path], step: int
) -> None:
    code, out, err = run(
        capsys, "--scene", str(drive), *est_args(estimates), *QUICK, "--egomotion",
        "--egomotion-step", str(step), "--json",
    )  # fmt: skip
    assert code == 0, err
    ego = json.loads(out)["egomotion"]
    outside = OUTSIDE.replace("0000000001", f"{step:010d}")
    assert (ego["step"], ego["gaps"], ego["problems"]) == (step, [], [outside])
    assert ego["label"].startswith("ground-truth-free")
    _, _, camera = geometry(drive)
    frames = sorted(p.stem for p in (drive / "image_02" / "data").glob("*.png"))
    # what the CLI gives the core (equal to the hand interpolation to 2e-7: the next test; the
    # sums' counts are not stable to a 2e-7 change of the motion)
    motions = {t: cli_motion(drive, t, t + step) for t in image_motions(drive, step)}
    assert sorted(motions) == list(range(1, len(frames) - step))
    greys = [grey(drive / "image_02" / "data" / f"{f}.png") for f in frames]
    for method, folder in estimates.items():
        maps = [
            prepare_frame(np.load(folder / f"{f}.npy"), g)
            for f, g in zip(frames, greys, strict=True)
        ]
        expected = None
        for t, motion in motions.items():
            one = egomotion_residual(maps[t], maps[t + step], motion, camera)
            expected = one if expected is None else expected + one
        assert expected is not None
        got = ego["methods"][method]
        assert got["pairs"] == len(frames) - step - 1
        sums = got["sums"]["gtfree:all"]
        assert list(sums) == list(expected.columns)
        np.testing.assert_allclose(list(sums.values()), expected.sums[0], rtol=1e-9)
        np.testing.assert_allclose(got["offsets"], expected.offsets, atol=1e-9)
        values = got["criteria"]["gtfree:all"]
        assert values["mean_abs"] == pytest.approx(sums["sum_abs"] / sums["n_residual"])
        assert values["n_residual"] > 0.1 * values["n"]


def test_the_motion_is_the_oxts_poses_interpolated_at_the_image_stamps(drive: Path) -> None:
    """What ``eval`` gives the core is the hand interpolation, not the per-sample motion.

    The per-sample motion (oxts stamps, 2–13 ms off the images) differs by up to 5.4 cm of
    about 0.78 m, so this fails if the poses are taken at the oxts samples' own stamps.
    """
    hand = image_motions(drive)
    samples = oxts_unit_poses(drive)
    _, imu_to_camera, _ = geometry(drive)
    per_sample = [pose @ np.linalg.inv(imu_to_camera) for pose in samples]
    moved_by = []
    for t, expected in hand.items():
        motion = cli_motion(drive, t, t + 1)
        # 2e-7: KITTI's printed rotations are orthonormal to about 1e-7, and the rigid
        # inverse (Rᵀ) of the mount is not its exact inverse (np.linalg.inv here)
        np.testing.assert_allclose(motion, expected, rtol=0, atol=2e-7)
        np.testing.assert_allclose(motion[:3, 3], expected[:3, 3], rtol=0, atol=1e-9)
        at_samples = np.linalg.inv(per_sample[t]) @ per_sample[t + 1]
        moved_by.append(np.linalg.norm(motion[:3, 3] - at_samples[:3, 3]))
    assert 0.05 < max(moved_by) < 0.055
    assert min(moved_by) > 0.02
    with pytest.raises(ExtrapolationError, match=r"before its oldest sample .* by 12\.698 ms"):
        cli_motion(drive, 0, 1)


def test_the_motion_is_the_camera_driving_forward_as_the_oxts_say(
    drive: Path, estimates: dict[str, Path]
) -> None:
    """The convention, two ways: the oxts forward speed (``vf``) times the time between the
    images; and the estimates themselves, which agree far better moved by the motion than by
    its inverse or by none.
    """
    _, _, camera = geometry(drive)
    stamps = stamps_ns(drive, "image_02") / 1e9
    no_fit = EgoMotionOptions(fit_offset=False)
    for t in range(1, len(stamps) - 1):
        motion = cli_motion(drive, t, t + 1)  # what the CLI gives the core
        speed = np.mean(
            [np.loadtxt(drive / "oxts" / "data" / f"{i:010d}.txt")[8] for i in (t, t + 1)]
        )
        forward = speed * (stamps[t + 1] - stamps[t])  # ≈ 0.78 m at 7.4–8 m/s, 10 Hz
        np.testing.assert_allclose(motion[:3, 3], [0, 0, forward], atol=0.02)
        if t % 4 != 1:
            continue
        frames = [prepare_frame(np.load(estimates["sgbm"] / f"{i:010d}.npy"),
                                grey(drive / "image_02" / "data" / f"{i:010d}.png"))
                  for i in (t, t + 1)]  # fmt: skip
        motions = {"right": motion, "inverted": np.linalg.inv(motion), "none": np.eye(4)}
        residual = {
            name: egomotion_residual(*frames, moved, camera, options=no_fit).summary("all")
            for name, moved in motions.items()
        }
        mean = {name: one["mean_abs"] for name, one in residual.items()}
        assert mean["right"] < 0.6 * min(mean["inverted"], mean["none"]), mean


def test_the_text_table_is_labelled_and_counts_the_masks(
    capsys: pytest.CaptureFixture[str], drive: Path, estimates: dict[str, Path]
) -> None:
    argv = ("--scene", str(drive), *est_args(estimates), *QUICK, "--egomotion")
    code, out, err = run(capsys, *argv)
    assert code == 0, err
    ego = json.loads(run(capsys, *argv, "--json")[1])["egomotion"]
    text = out[out.index("ego-motion residual over frames") :]
    assert "ground-truth-free" in text
    assert "not bias" in text
    for method in METHODS:
        values = ego["methods"][method]["criteria"]["gtfree:all"]
        parts = [line.split()[2:] for line in text.splitlines()
                 if re.match(rf"gtfree:all\s+{method}\s", line)]  # fmt: skip
        cells = [cell for part in parts for cell in part]  # the table is split by columns
        columns = ["n_residual", "mean_abs", "rms", "bad_0.5", "bad_2", "bad_4", "mean_abs_z",
                   "rms_z", "n_missing", "n_border", "n_hidden", "n_missing_target", "n_edge",
                   "n_moving"]  # fmt: skip
        assert len(cells) == len(columns)
        for cell, column in zip(cells, columns, strict=True):
            if column.startswith("n_"):
                assert int(cell) == values[column], column
            else:
                assert float(cell) == pytest.approx(values[column], rel=1e-3), column
        assert f"{method}: 1 run (0000000000–0000000010), 9 pairs; offset removed" in text


def _copy_drive(drive: Path, target: Path, oxts: bool = True) -> Path:
    """The drive's day folder rebuilt under ``target`` (streams linked, oxts copied)."""
    day = target / drive.parent.name
    copy = day / drive.name
    copy.mkdir(parents=True)
    for calib in drive.parent.glob("calib_*.txt"):
        shutil.copy(calib, day / calib.name)
    for stream in ("image_02", "image_03", "velodyne_points"):
        (copy / stream).symlink_to(drive / stream)
    if oxts:
        shutil.copytree(drive / "oxts", copy / "oxts")
    return copy


@pytest.mark.parametrize("latitude", ["nan", "95.0", "stamp"])
def test_an_unusable_pose_is_a_problem_of_its_pairs_only(
    capsys: pytest.CaptureFixture[str],
    drive: Path,
    estimates: dict[str, Path],
    tmp_path: Path,
    latitude: str,
) -> None:
    """oxts sample 5 unusable: the images 5 and 6 lie beside it (2.3–5.7 ms before samples 5
    and 6), so their poses would be interpolated across it: frames 5 and 6 lose their pairs."""
    copy = _copy_drive(drive, tmp_path)
    bad = copy / "oxts" / "data" / "0000000005.txt"
    if latitude == "stamp":  # sample 5 stamped as sample 4: not after it
        bad = copy / "oxts" / "timestamps.txt"
        lines = bad.read_text().splitlines()
        lines[5] = lines[4]
        bad.write_text("\n".join(lines) + "\n")
    else:
        bad.write_text(f"{latitude} " + " ".join(bad.read_text().split()[1:]) + "\n")
    code, out, err = run(capsys, "--scene", str(copy), *est_args(estimates), *QUICK,
                         "--egomotion", "--json")  # fmt: skip
    assert code == 0, err
    ego = json.loads(out)["egomotion"]
    assert ego["problems"][0].startswith(OUTSIDE.split("; 11 sample(s)", maxsplit=1)[0])
    assert [p.split(":")[0] for p in ego["problems"][1:]] == [
        "no pair 0000000004 → 0000000005 (sgbm, bm_fast)",
        "no pair 0000000005 → 0000000006 (sgbm, bm_fast)",
        "no pair 0000000006 → 0000000007 (sgbm, bm_fast)",
    ]
    assert all(str(bad) in p for p in ego["problems"][1:])
    if latitude == "stamp":
        assert (
            "the stamp of 0000000005 (1317046451.334622347 s) is not after that of 0000000004 "
            "(1317046451.334622347 s), not a pose"
        ) in ego["problems"][1]
    assert ego["methods"]["sgbm"]["pairs"] == 6
    code, out, _ = run(capsys, "--scene", str(copy), *est_args(estimates), *QUICK, "--egomotion")
    assert "problem: no pair 0000000004 → 0000000005 (sgbm, bm_fast)" in out


def test_a_missing_estimate_is_a_gap(
    capsys: pytest.CaptureFixture[str], drive: Path, estimates: dict[str, Path]
) -> None:
    files = [f"sgbm={p}" for p in sorted(estimates["sgbm"].glob("*.npy")) if p.stem != "0000000004"]
    argv = ["--scene", str(drive), *(a for f in files for a in ("--est", f)), *QUICK]
    code, out, err = run(capsys, *argv, "--egomotion", "--json")
    assert code == 0, err
    ego = json.loads(out)["egomotion"]
    assert ego["methods"]["sgbm"]["pairs"] == 7  # 0 → 1 is outside the oxts samples
    assert ego["methods"]["sgbm"]["runs"][1][0] == "0000000005"
    [gap] = ego["gaps"]
    assert (gap["after"], gap["before"], gap["missing"], gap["unscored"]) == (
        "0000000003", "0000000005", [], 1,
    )  # fmt: skip


@pytest.mark.parametrize(
    ("where", "extra", "words"),
    [
        ("middeval3-training-Q/Adirondack", (), "--egomotion needs the camera's pose"),
        ("sceneflow-flyingthings3d-seq", (), "--egomotion needs the camera's pose"),
        (DRIVE, ("--frame", "0000000003"), "--egomotion scores pairs of consecutive frames"),
        (DRIVE, ("--egomotion-step", "0"), "--egomotion-step must be at least 1"),
        (DRIVE, ("--protocol", "kitti2015"), "--egomotion does not apply with --protocol"),
    ],
)
def test_bad_input_is_one_line_exit_2(
    capsys: pytest.CaptureFixture[str], shared_data: Path, tmp_path: Path, where, extra, words
) -> None:
    scene = shared_data / where
    if where == DRIVE:
        estimate = tmp_path / "0000000003.npy"
        np.save(estimate, np.ones((375, 1242), np.float32))
    else:
        estimate = next(scene.glob("disp0GT.pfm"), scene / "Disparity" / "0007.pfm")
    code, out, err = run(capsys, "--scene", str(scene), "--est", f"m={estimate}", *QUICK,
                         "--egomotion", *extra)  # fmt: skip
    assert (code, out) == (2, "")
    assert len(err.strip().splitlines()) == 1
    assert words in err


def test_a_drive_without_oxts_or_without_a_scene_is_one_line(
    capsys: pytest.CaptureFixture[str], drive: Path, estimates: dict[str, Path], tmp_path: Path
) -> None:
    copy = _copy_drive(drive, tmp_path, oxts=False)
    code, out, err = run(capsys, "--scene", str(copy), *est_args(estimates), "--egomotion")
    assert (code, out, len(err.strip().splitlines())) == (2, "", 1)
    assert "no oxts/data/ folder" in err
    gt = estimates["sgbm"] / "0000000000.npy"
    code, _, err = run(capsys, "--gt", str(gt), "--est", f"m={gt}", "--egomotion")
    assert code == 2
    assert "--egomotion scores the consecutive frames of a drive: give --scene DRIVE" in err
    code, _, err = run(capsys, "--scene", str(drive), "--est", f"m={gt}", "--egomotion-step", "2")
    assert code == 2
    assert "--egomotion-step K applies with --egomotion" in err


def test_without_egomotion_nothing_changes(
    capsys: pytest.CaptureFixture[str], drive: Path, estimates: dict[str, Path], tmp_path: Path
) -> None:
    argv = ("--scene", str(drive), *est_args(estimates), *QUICK)
    plain_code, plain, _ = run(capsys, *argv)
    code, with_ego, _ = run(capsys, *argv, "--egomotion")
    assert plain_code == code == 0
    assert "ego-motion" not in plain
    assert with_ego.startswith(plain.rstrip("\n") + "\n\nego-motion residual over frames")
    documents = [json.loads(run(capsys, *argv, *extra, "--json")[1])
                 for extra in ((), ("--egomotion",))]  # fmt: skip
    assert "egomotion" not in documents[0]
    assert "egomotion" not in documents[0]["provenance"]["configuration"]
    assert documents[1]["provenance"]["configuration"]["egomotion"] == {"step": 1}
    stored = documents[1].pop("egomotion")
    for document in documents:
        del document["provenance"]
    assert documents[0] == documents[1]
    from dispeval_ros.io.store import ResultsStore

    assert run(capsys, *argv, "--egomotion", "--out", str(tmp_path / "out"))[0] == 0
    with ResultsStore.open(tmp_path / "out") as store:
        [name] = store.sequences()
        assert store.sequence_info(name)[1]["egomotion"] == stored


# -- the README's example ----------------------------------------------------------------------

CLONE = README.parent


def readme_example() -> tuple[str, list[str], str]:
    """The example block's Python code, its ``eval`` command, the README text after it."""
    block = readme_block("egomotion-example", "bash")
    code = re.search(r'python -c "(.*?)"\n', block, re.S)
    assert code
    command = shlex.split(block[block.index("dispeval eval") :].replace("\\\n", " "))
    text = README.read_text(encoding="utf-8")
    after = text[text.index("<!-- /egomotion-example -->") :]
    return code.group(1), command[2:], after[: after.index("\n#")]


def test_the_readme_example_prints_the_readme_numbers(
    capsys: pytest.CaptureFixture[str], shared_data: Path, tmp_path: Path, monkeypatch
) -> None:
    code, command, text = readme_example()
    (tmp_path / "kitti-raw-drive-0048").symlink_to(shared_data / "kitti-raw-drive-0048")
    environment = {"PYTHONPATH": str(CLONE), "PATH": "/usr/bin:/bin"}
    subprocess.run([sys.executable, "-c", code], cwd=tmp_path, check=True, env=environment)
    monkeypatch.chdir(tmp_path)
    document = json.loads(run(capsys, *command, "--json")[1])
    summary = json.loads((tmp_path / "results" / "summary.json").read_text())
    [sequence] = summary["sequences"]
    rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
            for line in text.splitlines() if line.startswith(("| sgbm ", "| bm_fast "))}  # fmt: skip
    assert list(rows) == list(METHODS)
    ego = {m: document["egomotion"]["methods"][m]["criteria"]["gtfree:all"] for m in METHODS}
    lidar = {m: sequence["scores"][m]["all"] for m in METHODS}
    for method, cells in rows.items():
        one = ego[method]
        assert document["egomotion"]["methods"][method]["pairs"] == 9
        assert cells[:3] == [f"{one[k]:.2f}" for k in ("mean_abs", "rms", "bad_2")]
        assert cells[3] == f"{100 * one['n_residual'] / one['n']:.1f}"
        drift = document["egomotion"]["lidar_drift"]["methods"][method]["criteria"]["drift:all"]
        assert cells[4:7] == [f"{drift[k]:.2f}" for k in ("mean", "rms", "bad_1")]
        assert cells[7:] == [f"{lidar[method][k]:.2f}" for k in ("mae", "bmp", "d1")]
    text = " ".join(text.split())
    assert (
        f"scans, pooled over the 11 frames (`results/summary.json`, {lidar['sgbm']['n']} " in text
    )
    counts = [int(ego[m]["n_missing"]) for m in ("bm_fast", "sgbm")]
    assert (
        f"`n_missing` {counts[0]} of {int(ego['sgbm']['n'])} pixel pairs, SGBM {counts[1]})" in text
    )
    bad = [ego[m]["bad_0.5"] for m in ("bm_fast", "sgbm")]
    assert f"({bad[0]:.2f} % against {bad[1]:.2f} %)" in text
    assert ego["sgbm"]["mean_abs"] < ego["bm_fast"]["mean_abs"]  # "SGBM flickers less"
    assert lidar["sgbm"]["mae"] < lidar["bm_fast"]["mae"]  # "and is more accurate"
