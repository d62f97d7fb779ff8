"""KITTI raw drives as a ``make-bag`` source, and ``make-bag --est``.

The shared drive (``kitti-raw-drive-0048``, 11 frames) is made into a bag, scored with
``dispeval bag --gt-cloud`` (filter off), and the scores are compared with a projection of the
scans written here from the calibration files (``X_rect = R_rect_00·[R|T]·X``, pixel
``P_rect_02·X_rect``, nearest point per pixel, ``d = f·B/w``) against the method maps read back
from the bag with rosbags. The bag's ``/tf`` is compared with the devkit's
``convertOxtsToPose`` written here too. Nothing below calls the project's readers of these
files.
"""

from __future__ import annotations

import math
import shutil
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from bag_support import quaternion_matrix
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
from sample_feed import stored_scores

from dispeval_ros.cli.main import main
from dispeval_ros.io.store import ResultsStore

DRIVE = "kitti-raw-drive-0048/2011_09_26/2011_09_26_drive_0048_sync"
FRAMES = 11
METHODS = ("sgbm", "bm_fast")
CLOUD, LEFT_INFO, RIGHT_INFO = (
    "/lidar/points",
    "/stereo/left/camera_info",
    "/stereo/right/camera_info",
)


def _topic(name: str) -> str:
    return f"/stereo/{name}/disparity"


# -- independent readers of the KITTI raw files ------------------------------------------------


def _calib(file: Path) -> dict[str, np.ndarray]:
    values = {}
    for line in file.read_text().splitlines():
        key, _, rest = line.partition(":")
        try:
            values[key.strip()] = np.array([float(v) for v in rest.split()])
        except ValueError:
            continue  # calib_time
    return values


def _stamps(file: Path) -> list[int]:
    out = []
    for line in file.read_text().split("\n"):
        if line.strip():
            whole, fraction = line.strip().split(".")
            moment = datetime.strptime(whole, "%Y-%m-%d %H:%M:%S").replace(tzinfo=timezone.utc)
            out.append(int(moment.timestamp()) * 10**9 + int(fraction.ljust(9, "0")))
    return out


def _geometry(drive: Path) -> tuple[np.ndarray, float, float]:
    """``P_rect_02 · R_rect_00 · [R|T]`` (3×4), f and B."""
    cam = _calib(drive.parent / "calib_cam_to_cam.txt")
    velo = _calib(drive.parent / "calib_velo_to_cam.txt")
    p2, p3 = cam["P_rect_02"].reshape(3, 4), cam["P_rect_03"].reshape(3, 4)
    rect = np.eye(4)
    rect[:3, :3] = cam["R_rect_00"].reshape(3, 3)
    velo_to_cam = np.eye(4)
    velo_to_cam[:3, :3] = velo["R"].reshape(3, 3)
    velo_to_cam[:3, 3] = velo["T"]
    f = p2[0, 0]
    return p2 @ rect @ velo_to_cam, f, (p2[0, 3] - p3[0, 3]) / f


def _projected(scan: Path, matrix: np.ndarray, fb: float, shape: tuple[int, int]) -> np.ndarray:
    """The scan's disparity map: nearest point per pixel (smallest w), 0 where none."""
    xyz = np.fromfile(scan, dtype="<f4").reshape(-1, 4)[:, :3].astype(np.float64)
    uvw = np.c_[xyz, np.ones(len(xyz))] @ matrix.T
    w = uvw[:, 2]
    front = w > 0
    col = np.floor(uvw[front, 0] / w[front] + 0.5)
    row = np.floor(uvw[front, 1] / w[front] + 0.5)
    z = w[front]
    inside = (col >= 0) & (col < shape[1]) & (row >= 0) & (row < shape[0])
    col, row, z = col[inside].astype(int), row[inside].astype(int), z[inside]
    depth = np.full(shape, np.inf)
    np.minimum.at(depth, (row, col), z)
    disparity = np.zeros(shape)
    hit = np.isfinite(depth)
    disparity[hit] = fb / depth[hit]
    return disparity


def _oxts_poses(folder: Path) -> list[np.ndarray]:
    """The KITTI devkit's convertOxtsToPose, relative to the first sample."""
    er = 6378137.0
    rows = [np.loadtxt(f)[:6] for f in sorted((folder / "oxts" / "data").glob("*.txt"))]
    scale = math.cos(rows[0][0] * math.pi / 180.0)
    poses = []
    for lat, lon, alt, roll, pitch, yaw in rows:
        t = [
            scale * lon * math.pi * er / 180,
            scale * er * math.log(math.tan(math.pi * (90 + lat) / 360)),
            alt,
        ]
        rx = np.array(
            [[1, 0, 0], [0, math.cos(roll), -math.sin(roll)], [0, math.sin(roll), math.cos(roll)]]
        )
        ry = np.array(
            [
                [math.cos(pitch), 0, math.sin(pitch)],
                [0, 1, 0],
                [-math.sin(pitch), 0, math.cos(pitch)],
            ]
        )
        rz = np.array(
            [[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]]
        )
        pose = np.eye(4)
        pose[:3, :3] = rz @ ry @ rx
        pose[:3, 3] = t
        poses.append(pose)
    first = np.linalg.inv(poses[0])
    return [first @ pose for pose in poses]


def _messages(bag: Path, topic: str) -> list[tuple[int, Any]]:
    """(log time, message) of one topic, read with rosbags."""
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        return [
            (time, reader.deserialize(raw, c.msgtype))
            for c, time, raw in reader.messages(connections=connections)
        ]


def _disparity(msg: Any) -> tuple[np.ndarray, np.ndarray]:
    """A DisparityImage's map and its valid pixels (inside [min_disparity, max_disparity])."""
    image = msg.image
    values = np.frombuffer(bytes(image.data), dtype="<f4").reshape(image.height, image.width)
    return values, (values >= msg.min_disparity) & (values <= msg.max_disparity)


def _scores(gt: np.ndarray, est: np.ndarray, valid: np.ndarray) -> dict[str, float]:
    """Measures under ``--missing thesis`` (a missing estimate is E = 0), δ = 1 px.

    A valid 0.0 (SGBM's ``min_disparity`` is 0) and a missing pixel both score E = 0, so these
    numbers do not depend on how a 0.0 is read; the density (:func:`_density`) does.
    """
    points = gt > 0
    d = gt[points]
    e = np.where(valid[points], est[points], 0.0)
    error = np.abs(e - d)
    return {
        "n": float(points.sum()),
        "mae": float(error.mean()),
        "bmp": float(100 * (error > 1.0).mean()),
        "d1": float(100 * ((error > 3.0) & (error > 0.05 * d)).mean()),
    }


def _density(gt: np.ndarray, valid: np.ndarray) -> float:
    """The density as the message defines validity (a 0.0 inside the range is valid)."""
    return float(valid[gt > 0].mean())


# -- the drive into a bag, scored -------------------------------------------------------------


@pytest.fixture(scope="module")
def drive(shared_data: Path) -> Path:
    return shared_data / DRIVE


def _write_pfm(path: Path, values: np.ndarray) -> None:
    header = f"Pf\n{values.shape[1]} {values.shape[0]}\n-1\n".encode()
    path.write_bytes(header + np.flipud(values).astype("<f4").tobytes())


def _predictions(folder: Path, shape: tuple[int, int]) -> dict[int, np.ndarray]:
    """A network's output as users have it: frames 0–4 as 16-bit PNG (KITTI raw's 10-digit
    names), 5–7 as PFM (6 digits, inf = missing), 8–10 as NPY; 0 and inf are missing."""
    folder.mkdir()
    rng = np.random.default_rng(21)
    maps = {}
    for number in range(FRAMES):
        raw = rng.integers(1, 150 * 256, size=shape).astype(np.uint16)
        raw[rng.random(shape) < 0.2] = 0
        values = raw / 256.0
        if number < 5:
            cv2.imwrite(str(folder / f"{number:010d}.png"), raw)
        elif number < 8:
            floats = np.where(raw > 0, values, np.inf).astype(np.float32)
            _write_pfm(folder / f"{number:06d}.pfm", floats)
        else:
            np.save(folder / f"{number:06d}.npy", values.astype(np.float32))
        maps[number] = np.where(raw > 0, values, np.nan)
    return maps


@pytest.fixture(scope="module")
def predictions(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[int, np.ndarray]]:
    folder = tmp_path_factory.mktemp("est") / "psm"
    return folder, _predictions(folder, (375, 1242))


@pytest.fixture(scope="module")
def raw_bag(
    drive: Path,
    predictions: tuple[Path, dict[int, np.ndarray]],
    tmp_path_factory: pytest.TempPathFactory,
) -> Path:
    bag = tmp_path_factory.mktemp("kitti_raw") / "drive"
    est = f"psm={predictions[0]}"
    assert main(["make-bag", str(bag), "--scene", str(drive), "--est", est]) == 0
    return bag


def _bag_geometry(bag: Path) -> np.ndarray:
    """``P_left · (base_link → camera)⁻¹ · (base_link → velodyne)`` as the bag carries it."""
    ((_, tf_static),) = _messages(bag, "/tf_static")
    edges = {
        t.child_frame_id: quaternion_matrix(t.transform.translation, t.transform.rotation)
        for t in tf_static.transforms
        if t.header.frame_id == "base_link"
    }
    projection = np.asarray(_messages(bag, LEFT_INFO)[0][1].p).reshape(3, 4)
    return projection @ np.linalg.inv(edges["stereo_left"]) @ edges["velodyne"]


@pytest.mark.slow
@pytest.mark.data
def test_bag_scores_equal_an_independent_projection(
    raw_bag: Path, drive: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    methods = [arg for m in METHODS for arg in ("--method", f"{m}={_topic(m)}")]
    args = ["bag", str(raw_bag), "--gt-cloud", CLOUD, "--camera-info", LEFT_INFO, RIGHT_INFO]
    extra = ["--cloud-filter", "0", "--tolerance", "20", "--missing", "thesis"]
    assert main([*args, *methods, *extra, "--out", str(out)]) == 0
    stored = stored_scores(out)
    stamps = sorted({stamp for stamp, _ in stored})
    assert len(stamps) == FRAMES
    calib, f, baseline = _geometry(drive)
    carried = _bag_geometry(raw_bag)
    # ROS carries KITTI's 7-digit, not quite orthonormal rotations as quaternions: the same
    # geometry to 5e-5 (relative 4e-4 on the smallest entries), a few points a frame move to
    # a neighbouring pixel.
    np.testing.assert_allclose(carried, calib, rtol=1e-3, atol=1e-4)
    scans = sorted((drive / "velodyne_points" / "data").glob("*.bin"))
    shape = cv2.imread(str(sorted((drive / "image_02" / "data").glob("*.png"))[0])).shape[:2]
    maps = {method: _messages(raw_bag, _topic(method)) for method in METHODS}
    assert all(len(messages) == FRAMES for messages in maps.values())
    for index, scan in enumerate(scans):
        gt = _projected(scan, carried, f * baseline, shape)
        raw = _projected(scan, calib, f * baseline, shape)
        assert int((gt > 0).sum()) > 15_000
        assert int(((gt > 0) != (raw > 0)).sum()) <= 8, index  # measured: 0–6 pixels
        for method in METHODS:
            est, valid = _disparity(maps[method][index][1])
            got = stored[(stamps[index], method)]["all"]
            expected = _scores(gt, est, valid)
            n = expected["n"]
            assert got["n"] == n, (method, index)
            # The project's GT is float32 (f·B/w rounded once): 1e-5 px a point at most.
            assert got["mae"] == pytest.approx(expected["mae"], abs=2e-5), (method, index)
            for name in ("bmp", "d1"):  # a point within 1e-5 px of a threshold may flip
                assert abs(got[name] - expected[name]) <= 100 / n + 1e-9, (method, index, name)
            assert got["density"] == pytest.approx(_density(gt, valid), rel=1e-9), (method, index)


@pytest.mark.data
def test_the_default_tolerance_says_how_far_the_scans_are(raw_bag: Path, tmp_path: Path) -> None:
    """KITTI stamps its scans ~10.5 ms from the images: with the default 10 ms nothing pairs,
    and each method's problem row says how far the nearest GT stamps were (not a silent 0)."""
    out = tmp_path / "out"
    methods = [arg for m in METHODS for arg in ("--method", f"{m}={_topic(m)}")]
    args = ["bag", str(raw_bag), "--gt-cloud", CLOUD, "--camera-info", LEFT_INFO, RIGHT_INFO]
    assert main([*args, *methods, "--out", str(out)]) == 0
    with ResultsStore.open(out) as store:
        (sequence,) = store.sequences()
        for method, found in store.match_counts(sequence).items():
            assert (found.matched, found.unmatched, found.dropped) == (0, FRAMES, FRAMES), method
        hints = {problem.method: problem.message for problem in store.problems(sequence)}
    assert set(hints) == set(METHODS)
    for method, message in hints.items():
        assert message.startswith(f"{FRAMES} estimate(s) of {method} found no {CLOUD} frame")
        assert "within --tolerance 10 ms" in message
        low, high = (float(v) for v in message.split("were ")[1].split(" ms")[0].split("–"))
        assert 10.0 < low <= high < 11.0  # the gaps make-bag prints (up to 10.55 ms)


@pytest.mark.slow
@pytest.mark.data
def test_streams_keep_their_stamps_and_tf_follows_the_oxts(raw_bag: Path, drive: Path) -> None:
    for topic, stream in (
        ("/stereo/left/image_rect", "image_02"),
        ("/stereo/right/image_rect", "image_03"),
        (RIGHT_INFO, "image_03"),
        (CLOUD, "velodyne_points"),
        (_topic("sgbm"), "image_02"),
    ):
        stamps = [
            m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
            for _, m in _messages(raw_bag, topic)
        ]
        assert stamps == _stamps(drive / stream / "timestamps.txt"), topic
    assert [m.header.frame_id for _, m in _messages(raw_bag, CLOUD)] == ["velodyne"] * FRAMES
    tf = _messages(raw_bag, "/tf")
    assert len(tf) == FRAMES
    poses = _oxts_poses(drive)
    for (log_time, msg), stamp, pose in zip(
        tf, _stamps(drive / "oxts" / "timestamps.txt"), poses, strict=True
    ):
        (edge,) = msg.transforms
        assert (edge.header.frame_id, edge.child_frame_id) == ("odom", "base_link")
        assert edge.header.stamp.sec * 10**9 + edge.header.stamp.nanosec == stamp == log_time
        matrix = quaternion_matrix(edge.transform.translation, edge.transform.rotation)
        np.testing.assert_allclose(matrix[:3, 3], pose[:3, 3], rtol=0, atol=1e-6)
        np.testing.assert_allclose(matrix[:3, :3], pose[:3, :3], rtol=0, atol=1e-9)
    # base_link is the oxts unit: base_link → velodyne is calib_imu_to_velo inverted.
    imu = _calib(drive.parent / "calib_imu_to_velo.txt")
    imu_to_velo = np.eye(4)
    imu_to_velo[:3, :3], imu_to_velo[:3, 3] = imu["R"].reshape(3, 3), imu["T"]
    ((_, tf_static),) = _messages(raw_bag, "/tf_static")
    (mount,) = [t for t in tf_static.transforms if t.child_frame_id == "velodyne"]
    assert mount.header.frame_id == "base_link"
    carried = quaternion_matrix(mount.transform.translation, mount.transform.rotation)
    np.testing.assert_allclose(carried, np.linalg.inv(imu_to_velo), atol=1e-5)
    # About 7.4 m/s: the last of 11 samples (1.03 s) is 7–8 m ahead of the first.
    assert 7.0 < float(np.linalg.norm(poses[-1][:3, 3])) < 8.0
    # No GT image topic: the scans are the reference.
    with AnyReader([raw_bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        topics = {c.topic for c in reader.connections}
    assert "/stereo/ground_truth/disparity" not in topics
    assert {"/tf_static", CLOUD, LEFT_INFO, RIGHT_INFO} <= topics


@pytest.mark.slow
@pytest.mark.data
def test_est_round_trip(
    raw_bag: Path, drive: Path, predictions: tuple[Path, dict[int, np.ndarray]]
) -> None:
    _, f, baseline = _geometry(drive)
    messages = _messages(raw_bag, _topic("psm"))
    left = _messages(raw_bag, "/stereo/left/image_rect")
    assert len(messages) == FRAMES
    for number, ((_, msg), (_, image)) in enumerate(zip(messages, left, strict=True)):
        assert msg.header.stamp == image.header.stamp
        values, valid = _disparity(msg)
        expected = predictions[1][number]
        np.testing.assert_array_equal(valid, np.isfinite(expected))
        np.testing.assert_array_equal(values[valid], expected[valid].astype(np.float32))
        assert (msg.f, msg.t) == pytest.approx((f, baseline), rel=1e-6)  # float32 fields


# -- bad drives: one line, exit 2, nothing written --------------------------------------------


def _copy_drive(drive: Path, root: Path) -> Path:
    """The shared drive as symlinks below ``root/2011_09_26`` (files can then be replaced)."""
    day = root / drive.parent.name
    copy = day / drive.name
    for calib in drive.parent.glob("calib_*.txt"):
        day.mkdir(parents=True, exist_ok=True)
        (day / calib.name).symlink_to(calib)
    for stream in drive.iterdir():
        (copy / stream.name / "data").mkdir(parents=True)
        for entry in stream.iterdir():
            if entry.is_file():
                (copy / stream.name / entry.name).symlink_to(entry)
        for entry in (stream / "data").iterdir():
            (copy / stream.name / "data" / entry.name).symlink_to(entry)
    return copy


def _no_stream(copy: Path) -> None:
    shutil.rmtree(copy / "velodyne_points")


def _scan_without_stamp(copy: Path) -> None:
    (copy / "velodyne_points" / "data" / "0000000010.bin").unlink()


def _stream_short(copy: Path) -> None:
    """velodyne_points one frame short, consistently (its timestamps cut too)."""
    _scan_without_stamp(copy)
    file = copy / "velodyne_points" / "timestamps.txt"
    lines = file.read_text().splitlines()[:-1]
    file.unlink()
    file.write_text("\n".join(lines) + "\n")


def _bad_stamp(copy: Path) -> None:
    file = copy / "image_03" / "timestamps.txt"
    lines = file.read_text().splitlines()
    file.unlink()
    lines[2] = "2011-09-26 14:14:11,118196992"
    file.write_text("\n".join(lines) + "\n")


def _no_p_rect_03(copy: Path) -> None:
    file = copy.parent / "calib_cam_to_cam.txt"
    lines = [line for line in file.read_text().splitlines() if not line.startswith("P_rect_03")]
    file.unlink()
    file.write_text("\n".join(lines) + "\n")


def _second_drive(copy: Path) -> Path:
    (copy.parent / "2011_09_26_drive_0001_sync" / "image_02" / "data").mkdir(parents=True)
    return copy.parent


@pytest.mark.data
@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (_no_stream, "no velodyne_points/data/ folder: a KITTI raw drive needs"),
        (_scan_without_stamp, "timestamps.txt: 11 timestamps for the 10 files of velodyne"),
        (
            _stream_short,
            "velodyne_points has 10 frames, image_02 11: frame(s) 0000000010 of image_02 "
            "missing in velodyne_points",
        ),
        (_bad_stamp, "image_03/timestamps.txt: line 3 is not a timestamp"),
        (_no_p_rect_03, "calib_cam_to_cam.txt: missing field 'P_rect_03'"),
        (
            _second_drive,
            "a day folder with 2 drives (2011_09_26_drive_0001_sync, 2011_09_26_drive_0048_sync)",
        ),
    ],
)
def test_bad_drives_are_refused(
    damage: Any, message: str, drive: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    copy = _copy_drive(drive, tmp_path / "in")
    scene = damage(copy) or copy
    out = tmp_path / "bag"
    assert main(["make-bag", str(out), "--scene", str(scene)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert message in err, err
    assert not out.exists()


@pytest.mark.data
@pytest.mark.parametrize(
    ("size", "skip", "message"),
    [
        ((375, 1242), 0, "no map for frame 0 (expected a file named by the frame's number"),
        ((370, 1242), None, "--est psm map is 1242×370, the images are 1242×375"),
    ],
)
def test_bad_est_folders_are_refused(
    size: tuple[int, int],
    skip: int | None,
    message: str,
    drive: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    folder = tmp_path / "psm"
    _predictions(folder, size)
    for file in folder.iterdir():
        if int(file.stem) == skip:
            file.unlink()
    out = tmp_path / "bag"
    args = ["make-bag", str(out), "--scene", str(drive), "--est", f"psm={folder}"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert message in err, err
    assert not out.exists()


@pytest.mark.data
def test_kitti_lidar_scene_says_its_gt_is_the_projected_scan(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "est"
    folder.mkdir()
    estimate = np.full((375, 1242), 20 * 256, dtype=np.uint16)
    cv2.imwrite(str(folder / "000000.png"), estimate)  # a single-frame scene is frame 0
    bag = tmp_path / "bag"
    scene = shared_data / "kitti-lidar" / "stereo-rcnn-demo"
    assert main(["make-bag", str(bag), "--scene", str(scene), "--est", f"flat={folder}"]) == 0
    out = " ".join(capsys.readouterr().out.split())  # the line is wrapped at the text width
    assert (
        "ground truth: /stereo/ground_truth/disparity = the LiDAR scan projected into the left "
        "camera (parallax filter 7,0.1), not a measured dense map" in out
    )
    ((_, msg),) = _messages(bag, _topic("flat"))
    values, valid = _disparity(msg)
    assert valid.all()
    assert (values == 20.0).all()


@pytest.mark.data
def test_a_drive_is_a_scene_of_kitti_lidar_frames(drive: Path) -> None:
    from dispeval_ros.io.scenes import list_frames

    frames = list_frames(drive)
    assert [f.name for f in frames] == [f"{drive.name}_{n:010d}" for n in range(FRAMES)]
    calib, f, baseline = _geometry(drive)
    scans = sorted((drive / "velodyne_points" / "data").glob("*.bin"))
    for frame, scan in zip(frames, scans, strict=True):
        assert frame.layout == "kitti-lidar"
        projected = _projected(scan, calib, f * baseline, frame.gt.shape)
        kept = frame.gt > 0
        # The scene's GT is the projection with the parallax filter (7,0.1): it only removes.
        assert not (kept & ~(projected > 0)).any()
        np.testing.assert_allclose(frame.gt[kept], projected[kept], rtol=1e-6)
        assert 0.02 < 1 - kept.sum() / (projected > 0).sum() < 0.10


@pytest.mark.data
def test_a_day_folder_with_one_drive_is_that_drive(drive: Path) -> None:
    from dispeval_ros.offline.make_bag import dataset_frames

    first = next(dataset_frames(drive.parent))
    assert first.gt is None
    assert first.number == 0
    assert first.stamps is not None
    assert first.stamps.left == _stamps(drive / "image_02" / "timestamps.txt")[0]
    assert first.stamps.cloud == _stamps(drive / "velodyne_points" / "timestamps.txt")[0]
