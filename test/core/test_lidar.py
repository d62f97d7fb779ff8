"""LiDAR ground truth: PointCloud2 decoding, static transform chains, projection and filter.

The projection is checked against :func:`reference_projection`, a straightforward loop over the
points written independently of the kernel (step by step: ``T``, then ``R``, then ``P``), on
synthetic clouds in every PointCloud2 layout and on the real KITTI scans.
"""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.projection import CloudFilter, project_cloud, rectified_projection
from dispeval_ros.core.transforms import (
    StaticTransform,
    TransformTree,
    invert_rigid,
    matrix_from_pose,
    pose_from_matrix,
    rigid_matrix,
)
from dispeval_ros.errors import CalibrationError, ConfigurationError, InputError
from dispeval_ros.io.encoders import cloud_to_msg, tf_static_to_msg
from dispeval_ros.io.files import read_disparity
from dispeval_ros.io.lidar import read_extrinsic, read_lidar_calib, read_velodyne_bin
from dispeval_ros.io.messages import (
    cloud_from_msg,
    rectified_camera_from_info,
    static_transforms_from_msg,
)

KITTI_FRAMES = ("000010", "000043", "000112", "000150")


# -- the independent reference ------------------------------------------------------------


def reference_projection(
    points: np.ndarray,
    extrinsic: np.ndarray,
    rect: np.ndarray,
    p: np.ndarray,
    shape: tuple[int, int],
    camera: Camera,
    window: int = 0,
    gap: float = 0.1,
) -> np.ndarray:
    """Loop over the points: transform, rectify, project, round half up, z-buffer, filter."""
    height, width = shape
    nearest: dict[tuple[int, int], float] = {}
    r4 = np.eye(4)
    r4[:3, :3] = rect
    for x, y, z in points.astype(np.float64):
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            continue
        camera_point = extrinsic @ np.array([x, y, z, 1.0])
        rectified = r4 @ camera_point
        uvw = p @ rectified
        w = uvw[2]
        if w <= 0:
            continue
        col = math.floor(uvw[0] / w + 0.5)
        row = math.floor(uvw[1] / w + 0.5)
        if not (0 <= col < width and 0 <= row < height):
            continue
        if w < nearest.get((row, col), math.inf):
            nearest[(row, col)] = w
    out = np.zeros(shape, np.float32)
    half = window // 2
    for (row, col), z in nearest.items():
        hidden = window > 1 and any(
            nearest.get((r, c), math.inf) * (1 + gap) < z
            for r in range(row - half, row + half + 1)
            for c in range(col - half, col + half + 1)
        )
        if not hidden:
            out[row, col] = camera.fb / z - camera.doffs
    return out


# -- synthetic scene ----------------------------------------------------------------------

SHAPE = (60, 80)
CAMERA = Camera(f=50.0, baseline=0.5)
P_LEFT = np.array([[50.0, 0, 39.5, 0], [0, 50.0, 29.5, 0], [0, 0, 1, 0]])
RECT = matrix_from_pose([0, 0, 0], [0.01, -0.02, 0.005, 1])[:3, :3]
# LiDAR (x forward, y left, z up) 0.3 m above and 0.5 m behind the camera (z forward, y down).
LIDAR_TO_CAMERA = np.array(
    [[0, -1, 0, 0.0], [0, 0, -1, -0.3], [1, 0, 0, -0.5], [0, 0, 0, 1]], dtype=np.float64
)


def synthetic_cloud(seed: int = 0, n: int = 6000) -> np.ndarray:
    """A wall at 20 m, a box at 5 m in front of it, some points behind the LiDAR, a few NaN."""
    rng = np.random.default_rng(seed)
    wall = np.column_stack([np.full(n, 20.0), rng.uniform(-15, 15, n), rng.uniform(-10, 10, n)])
    box = np.column_stack(
        [rng.uniform(5.0, 5.5, n // 3), rng.uniform(-1, 1, n // 3), rng.uniform(-1, 1.0, n // 3)]
    )
    behind = np.column_stack([rng.uniform(-20, -1, 200), rng.uniform(-5, 5, 200), np.zeros(200)])
    cloud = np.vstack([wall, box, behind]).astype(np.float32)
    cloud[rng.choice(cloud.shape[0], 50, replace=False), rng.integers(0, 3)] = np.nan
    return cloud


def test_projection_matches_loop_filter_off_and_on() -> None:
    cloud = synthetic_cloud()
    matrix = rectified_projection(LIDAR_TO_CAMERA, RECT, P_LEFT)
    for window, gap in ((0, 0.1), (5, 0.1), (3, 0.5)):
        expected = reference_projection(
            cloud, LIDAR_TO_CAMERA, RECT, P_LEFT, SHAPE, CAMERA, window, gap
        )
        result = project_cloud(cloud, matrix, SHAPE, CAMERA, CloudFilter(window, gap))
        np.testing.assert_array_equal(result.disparity > 0, expected > 0)
        np.testing.assert_allclose(result.disparity, expected, rtol=1e-6, atol=0)
        assert result.kept == int((expected > 0).sum())
    off = project_cloud(cloud, matrix, SHAPE, CAMERA, CloudFilter(0))
    on = project_cloud(cloud, matrix, SHAPE, CAMERA, CloudFilter(5, 0.1))
    assert off.points == cloud.shape[0] - 50
    assert off.in_front < off.points
    assert off.inside <= off.in_front
    assert off.removed == 0
    assert on.removed > 0
    assert on.kept + on.removed == off.kept


def test_nearest_point_wins_and_round_half_up() -> None:
    p = np.array([[10.0, 0, 0, 0], [0, 10.0, 0, 0], [0, 0, 1, 0]])
    camera = Camera(f=10.0, baseline=1.0)
    # Camera-frame points (identity extrinsic): u = 10·x/z, v = 10·y/z.
    points = np.array(
        [
            [0.05, 0.05, 1.0],  # u = v = 0.5 → pixel (1, 1) by round half up
            [0.1, 0.1, 2.0],  # same pixel, farther: loses
            [0.1, 0.1, 0.5],  # u = v = 2 → pixel (2, 2)
            [0.0, 0.0, -1.0],  # behind: dropped (would mirror into the image)
            [0.0, 0.0, 0.0],  # Z = 0: dropped
            [1.0, 0.0, 1.0],  # u = 10: outside a 5×5 image
        ],
        dtype=np.float64,
    )
    matrix = rectified_projection(np.eye(4), np.eye(3), p)
    result = project_cloud(points, matrix, (5, 5), camera, CloudFilter(0))
    expected = np.zeros((5, 5), np.float32)
    expected[1, 1] = 10.0  # f·B / Z = 10 / 1
    expected[2, 2] = 20.0
    np.testing.assert_array_equal(result.disparity, expected)
    assert (result.points, result.in_front, result.inside, result.kept) == (6, 4, 3, 2)
    # The nearer point at (2, 2) is nearer than (1, 1) by 50 %: a 3×3 filter drops (1, 1).
    filtered = project_cloud(points, matrix, (5, 5), camera, CloudFilter(3, 0.4))
    assert filtered.disparity[1, 1] == 0
    assert filtered.disparity[2, 2] == 20.0
    assert filtered.removed == 1
    # Under the gap (relative 1.0): kept.
    assert project_cloud(points, matrix, (5, 5), camera, CloudFilter(3, 1.0)).removed == 0


def test_cloud_filter_parse() -> None:
    assert CloudFilter.parse("0") == CloudFilter(0)
    assert not CloudFilter.parse("0").enabled
    assert CloudFilter.parse("5,0.2") == CloudFilter(5, 0.2)
    assert str(CloudFilter(5, 0.2)) == "5,0.2"
    for bad in ("5", "a,b", "2.5,0.1", "-3,0.1", "3,-1", "6,0.1"):
        with pytest.raises(ConfigurationError, match="cloud filter"):
            CloudFilter.parse(bad)


# -- PointCloud2 layouts -------------------------------------------------------------------


def _field(name: str, offset: int, datatype: int, count: int = 1) -> SimpleNamespace:
    return SimpleNamespace(name=name, offset=offset, datatype=datatype, count=count)


def _cloud_msg(
    points: np.ndarray,
    *,
    order: tuple[str, ...] = ("x", "y", "z"),
    dtype: str = "f4",
    bigendian: bool = False,
    extra: bool = False,
    point_padding: int = 0,
    height: int = 1,
    row_padding: int = 0,
    as_type: type = bytes,
) -> SimpleNamespace:
    """A PointCloud2-like message with the x, y, z fields in ``order`` among other fields."""
    endian = ">" if bigendian else "<"
    names: list[str] = []
    formats: list[str] = []
    if extra:
        names += ["intensity"]
        formats += [endian + "f4"]
    for name in order:
        names.append(name)
        formats.append(endian + dtype)
        if extra and name == order[0]:
            names.append("ring")
            formats.append(endian + "u2")
    record = np.dtype({"names": names, "formats": formats})
    itemsize = record.itemsize + point_padding
    record = np.dtype({"names": names, "formats": formats, "itemsize": itemsize})
    data = np.zeros(points.shape[0], dtype=record)
    for column, name in enumerate("xyz"):
        data[name] = points[:, column]
    if extra:
        data["intensity"] = 0.5
        data["ring"] = 7
    width = points.shape[0] // height
    rows = data.view(np.uint8).reshape(height, width * itemsize)
    padded = np.concatenate([rows, np.full((height, row_padding), 0xAB, np.uint8)], axis=1)
    datatype = {"f4": 7, "f8": 8}[dtype]
    fields = [
        _field(
            name,
            record.fields[name][1],
            7 if name == "intensity" else 4 if name == "ring" else datatype,
        )
        for name in names
    ]
    raw = padded.reshape(-1).tobytes()
    return SimpleNamespace(
        header=SimpleNamespace(stamp=SimpleNamespace(sec=3, nanosec=5), frame_id="velodyne"),
        height=height,
        width=width,
        fields=fields,
        is_bigendian=bigendian,
        point_step=itemsize,
        row_step=width * itemsize + row_padding,
        data=as_type(raw) if as_type is not np.ndarray else np.frombuffer(raw, np.uint8),
        is_dense=bool(np.isfinite(points).all()),
    )


LAYOUTS = {
    "plain": {},
    "permuted fields": {"order": ("z", "x", "y")},
    "extra fields": {"extra": True},
    "point padding": {"point_padding": 7, "extra": True},
    "organised": {"height": 4},
    "organised, padded rows": {"height": 4, "row_padding": 13},
    "big-endian": {"bigendian": True, "extra": True},
    "float64": {"dtype": "f8"},
    "big-endian float64 organised": {"dtype": "f8", "bigendian": True, "height": 2},
    "bytearray": {"as_type": bytearray},
    "numpy data": {"as_type": np.ndarray, "row_padding": 3, "height": 2},
    "memoryview": {"as_type": memoryview},
}


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_cloud_layouts_decode_and_project_like_the_loop(layout: str) -> None:
    cloud = synthetic_cloud(seed=1, n=3000)[:3200]
    frame = cloud_from_msg(_cloud_msg(cloud, **LAYOUTS[layout]), "/points")
    assert frame.frame_id == "velodyne"
    assert frame.stamp == 3_000_000_005
    assert frame.points.shape == cloud.shape
    np.testing.assert_array_equal(frame.points, cloud)  # NaN points kept, exact values
    matrix = rectified_projection(LIDAR_TO_CAMERA, RECT, P_LEFT)
    expected = reference_projection(cloud, LIDAR_TO_CAMERA, RECT, P_LEFT, SHAPE, CAMERA)
    result = project_cloud(frame.points, matrix, SHAPE, CAMERA, CloudFilter(0))
    np.testing.assert_allclose(result.disparity, expected, rtol=1e-6, atol=0)


def test_cloud_round_trip_through_rosbags_typestore() -> None:
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_HUMBLE)
    cloud = synthetic_cloud(seed=2, n=500)
    msg = cloud_to_msg(typestore, cloud, 42, "lidar", intensity=np.ones(cloud.shape[0]))
    raw = typestore.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2")
    back = typestore.deserialize_cdr(raw, "sensor_msgs/msg/PointCloud2")
    frame = cloud_from_msg(back)
    np.testing.assert_array_equal(frame.points, cloud)
    assert back.point_step == 16
    assert not back.is_dense


def test_cloud_errors_are_one_line() -> None:
    cloud = synthetic_cloud(n=100)[:90]
    msg = _cloud_msg(cloud)
    msg.fields = [f for f in msg.fields if f.name != "y"]
    with pytest.raises(
        InputError, match=r"PointCloud2 on /points: the cloud has no 'y' field \(fields: x, z\)"
    ):
        cloud_from_msg(msg, "/points")
    msg = _cloud_msg(cloud)
    msg.fields[0] = _field("x", 0, 4)
    with pytest.raises(InputError, match="datatype UINT16, expected FLOAT32"):
        cloud_from_msg(msg, "/points")
    msg = _cloud_msg(cloud)
    msg.data = msg.data[:-5]
    with pytest.raises(InputError, match=r"data has .* bytes, expected at least"):
        cloud_from_msg(msg, "/points")
    msg = _cloud_msg(cloud)
    msg.point_step = 8
    with pytest.raises(InputError, match="does not fit in point_step 8"):
        cloud_from_msg(msg, "/points")
    msg = _cloud_msg(cloud)
    msg.width, msg.height, msg.data = 0, 0, b""
    assert cloud_from_msg(msg).points.shape == (0, 3)
    with pytest.raises(InputError, match="N×3"):
        project_cloud(np.zeros((4, 2)), np.zeros((3, 4)), SHAPE, CAMERA)


# -- transforms ----------------------------------------------------------------------------


def test_pose_round_trip_and_inverse() -> None:
    rng = np.random.default_rng(5)
    for _ in range(20):
        q = rng.normal(size=4)
        matrix = matrix_from_pose(rng.normal(size=3), q)
        t, q_back = pose_from_matrix(matrix)
        np.testing.assert_allclose(matrix_from_pose(t, q_back), matrix, atol=1e-12)
        np.testing.assert_allclose(invert_rigid(matrix) @ matrix, np.eye(4), atol=1e-12)
    # 90° about z: x → y.
    quarter = matrix_from_pose([1, 2, 3], [0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4)])
    np.testing.assert_allclose(quarter @ [1, 0, 0, 1], [1, 3, 3, 1], atol=1e-12)


def test_rigid_matrix_forms_and_errors() -> None:
    pose = matrix_from_pose([0.1, 0.2, 0.3], [0, 0, 0, 1])
    np.testing.assert_array_equal(rigid_matrix(pose.reshape(-1)), pose)
    np.testing.assert_array_equal(rigid_matrix(pose[:3].reshape(-1)), pose)
    np.testing.assert_allclose(rigid_matrix([0.1, 0.2, 0.3, 0, 0, 0, 2]), pose)
    with pytest.raises(CalibrationError, match="not a rotation"):
        rigid_matrix(np.diag([2.0, 1, 1, 1]).reshape(-1))
    with pytest.raises(CalibrationError, match="got 5 numbers"):
        rigid_matrix([1, 2, 3, 4, 5])
    with pytest.raises(CalibrationError, match="non-zero quaternion"):
        rigid_matrix([0, 0, 0, 0, 0, 0, 0])


def test_transform_chain_composes_both_directions() -> None:
    base_to_lidar = matrix_from_pose([-0.27, 0, 1.7], [0, 0, 0.02, 1])
    base_to_camera = matrix_from_pose([0, 0.06, 1.6], [0.5, -0.5, 0.5, -0.5])
    camera_to_optical = matrix_from_pose([0, 0, 0], [-0.5, 0.5, -0.5, 0.5])
    tree = TransformTree()
    tree.add(
        [
            StaticTransform("base_link", "velodyne", base_to_lidar),
            StaticTransform("/base_link", "camera", base_to_camera),
            StaticTransform("camera", "camera_optical", camera_to_optical),
        ]
    )
    # points in velodyne → base_link → camera → camera_optical
    expected = invert_rigid(base_to_camera @ camera_to_optical) @ base_to_lidar
    np.testing.assert_allclose(tree.lookup("camera_optical", "velodyne"), expected, atol=1e-12)
    np.testing.assert_allclose(
        tree.lookup("velodyne", "camera_optical"), invert_rigid(expected), atol=1e-12
    )
    np.testing.assert_array_equal(tree.lookup("camera", "/camera"), np.eye(4))
    with pytest.raises(CalibrationError) as error:
        tree.lookup("camera_optical", "os_lidar")
    message = str(error.value)
    assert "'os_lidar'" in message
    assert "'camera_optical'" in message
    assert "base_link, camera, camera_optical, velodyne" in message
    with pytest.raises(CalibrationError, match="none"):
        TransformTree().lookup("a", "b")


def test_tf_static_message_round_trip() -> None:
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_HUMBLE)
    edges = [
        StaticTransform("base_link", "velodyne", matrix_from_pose([1, 2, 3], [0.1, 0.2, 0.3, 1])),
        StaticTransform("base_link", "cam", matrix_from_pose([0, 0, 1], [0, 0, 0, 1])),
    ]
    msg = tf_static_to_msg(typestore, edges, 7)
    raw = typestore.serialize_cdr(msg, "tf2_msgs/msg/TFMessage")
    back = static_transforms_from_msg(typestore.deserialize_cdr(raw, "tf2_msgs/msg/TFMessage"))
    assert [(e.parent, e.child) for e in back] == [("base_link", "velodyne"), ("base_link", "cam")]
    for original, decoded in zip(edges, back, strict=True):
        np.testing.assert_allclose(decoded.matrix, original.matrix, atol=1e-12)


def test_rectified_camera_from_info() -> None:
    info = SimpleNamespace(
        header=SimpleNamespace(frame_id="left_optical"),
        width=80,
        height=60,
        r=RECT.reshape(-1),
        p=P_LEFT.reshape(-1),
    )
    view = rectified_camera_from_info(info)
    assert (view.frame_id, view.width, view.height) == ("left_optical", 80, 60)
    np.testing.assert_array_equal(view.rectification, RECT)
    info.r = np.zeros(9)  # uncalibrated drivers: identity
    np.testing.assert_array_equal(rectified_camera_from_info(info).rectification, np.eye(3))
    for wrong in (2 * np.eye(3), np.diag([1.0, 1.0, -1.0]), np.full((3, 3), np.nan)):
        info.r = wrong.reshape(-1)  # scaled, a reflection (det −1), not finite
        with pytest.raises(CalibrationError, match="CameraInfo on /l: R is not a rotation"):
            rectified_camera_from_info(info, "/l")


def test_read_extrinsic(tmp_path: Path) -> None:
    pose = matrix_from_pose([0.1, -0.2, 0.3], [0.1, 0, 0, 1])
    file = tmp_path / "T.txt"
    file.write_text("# lidar to camera\n" + "\n".join(" ".join(map(str, r.tolist())) for r in pose))
    np.testing.assert_allclose(read_extrinsic(file), pose)
    t, q = pose_from_matrix(pose)
    file.write_text(" ".join(map(str, [*t.tolist(), *q.tolist()])))
    np.testing.assert_allclose(read_extrinsic(file), pose, atol=1e-12)
    file.write_text("1 2 3")
    with pytest.raises(CalibrationError, match=r"T\.txt: the extrinsic must be a 4×4"):
        read_extrinsic(file)
    file.write_text("x y z")
    with pytest.raises(CalibrationError, match="only numbers"):
        read_extrinsic(file)
    with pytest.raises(CalibrationError, match="not found"):
        read_extrinsic(tmp_path / "missing.txt")


# -- real KITTI scans ---------------------------------------------------------------------

# Per frame (README of kitti-lidar): N, with Z > 0, inside the image by the README's
# convention (0 ≤ u < W and 0 ≤ v < H before rounding).
README_COUNTS = {
    "stereo-rcnn-demo": (103_344, 55_831, 17_835),
    "000010": (123_451, 61_839, 20_615),
    "000043": (118_040, 59_792, 19_025),
    "000112": (117_388, 56_579, 16_864),
    "000150": (119_845, 59_745, 19_574),
}


def _kitti(shared_data: Path, frame: str) -> tuple[np.ndarray, object, Path]:
    root = shared_data / "kitti-lidar"
    if frame == "stereo-rcnn-demo":
        folder = root / "stereo-rcnn-demo"
        return (
            read_velodyne_bin(folder / "lidar.bin"),
            read_lidar_calib(folder / "calib.txt"),
            folder / "left.png",
        )
    folder = root / "kitti2015-with-velodyne"
    return (
        read_velodyne_bin(folder / "velodyne_points" / f"{frame}.bin"),
        read_lidar_calib(root / "raw-calib-2011_09_26"),
        folder / "image_02" / f"{frame}.png",
    )


@pytest.mark.data
def test_kitti_calibration_formats_agree(shared_data: Path) -> None:
    root = shared_data / "kitti-lidar"
    raw = read_lidar_calib(root / "raw-calib-2011_09_26")
    same = read_lidar_calib(root / "raw-calib-2011_09_26" / "calib_velo_to_cam.txt")
    obj = read_lidar_calib(root / "stereo-rcnn-demo" / "calib.txt")
    np.testing.assert_allclose(raw.matrix, obj.matrix, rtol=1e-12)
    np.testing.assert_array_equal(raw.matrix, same.matrix)
    camera = raw.camera
    assert camera.f == 721.5377
    assert camera.doffs == 0.0
    assert round(camera.baseline, 4) == 0.5327
    np.testing.assert_array_equal(raw.left[:, 3], [44.85728, 0.2163791, 0.002745884])


@pytest.mark.data
@pytest.mark.parametrize("frame", sorted(README_COUNTS))
def test_kitti_scan_counts_as_the_readme(shared_data: Path, frame: str) -> None:
    points, calibration, left = _kitti(shared_data, frame)
    height, width = cv2.imread(str(left), cv2.IMREAD_UNCHANGED).shape[:2]
    assert (height, width) == (375, 1242)
    homogeneous = np.column_stack([points.astype(np.float64), np.ones(len(points))])
    uvw = homogeneous @ calibration.matrix.T
    front = uvw[:, 2] > 0
    u = uvw[front, 0] / uvw[front, 2]
    v = uvw[front, 1] / uvw[front, 2]
    inside_readme = int(((u >= 0) & (u < width) & (v >= 0) & (v < height)).sum())
    assert (len(points), int(front.sum()), inside_readme) == README_COUNTS[frame]
    result = project_cloud(
        points, calibration.matrix, (height, width), calibration.camera, CloudFilter(0)
    )
    # Round half up: in the image when -0.5 ≤ u < W - 0.5 (a few edge points differ).
    inside = int(((u >= -0.5) & (u < width - 0.5) & (v >= -0.5) & (v < height - 0.5)).sum())
    assert (result.points, result.in_front, result.inside) == (
        len(points),
        int(front.sum()),
        inside,
    )
    assert abs(result.inside - inside_readme) < 0.002 * inside_readme


@pytest.mark.data
def test_kitti_projection_matches_the_loop(shared_data: Path) -> None:
    points, calibration, _ = _kitti(shared_data, "stereo-rcnn-demo")
    # The loop only needs the points in front of the LiDAR's forward half (speed).
    points = points[points[:, 0] > 0]
    for window in (0, DEFAULT_WINDOW):
        expected = reference_projection(
            points,
            calibration.extrinsic,
            calibration.rectification,
            calibration.left,
            (375, 1242),
            calibration.camera,
            window,
            0.1,
        )
        result = project_cloud(
            points, calibration.matrix, (375, 1242), calibration.camera, CloudFilter(window, 0.1)
        )
        np.testing.assert_array_equal(result.disparity > 0, expected > 0)
        np.testing.assert_allclose(result.disparity, expected, rtol=1e-6, atol=0)
    lidar = result.disparity[result.disparity > 0]
    assert 4.8 < lidar.min() < 4.9
    assert 163.0 < lidar.max() < 163.2


DEFAULT_WINDOW = CloudFilter().window


@pytest.mark.data
@pytest.mark.parametrize("frame", KITTI_FRAMES)
def test_kitti_scan_agrees_with_official_gt(shared_data: Path, frame: str) -> None:
    points, calibration, _left = _kitti(shared_data, frame)
    official = read_disparity(
        shared_data
        / "kitti-lidar"
        / "kitti2015-with-velodyne"
        / "gt"
        / "disp_occ_0"
        / f"{frame}.png"
    )
    errors = {}
    for name, chosen in (("off", CloudFilter(0)), ("on", CloudFilter())):
        result = project_cloud(
            points, calibration.matrix, official.shape, calibration.camera, chosen
        )
        both = (result.disparity > 0) & (official > 0)
        assert both.sum() > 0.4 * result.kept  # the official GT misses sky-facing edges, glass
        errors[name] = np.abs(result.disparity[both] - official[both])
    assert np.median(errors["off"]) < 0.1  # README: 0.019–0.094 px
    assert (errors["off"] < 1).mean() > 0.95
    # The parallax filter removes most of the disagreement (README trap 3).
    assert (errors["on"] > 3).mean() < 0.5 * (errors["off"] > 3).mean()
    assert (errors["on"] > 3).mean() < 0.005


@pytest.mark.data
def test_kitti_sgbm_against_the_scan_and_a_wrong_extrinsic(shared_data: Path) -> None:
    from dispeval_ros.core import Evaluator

    points, calibration, left_file = _kitti(shared_data, "000010")
    left = cv2.imread(str(left_file), cv2.IMREAD_GRAYSCALE)
    right_file = left_file.parent.parent / "image_03" / left_file.name
    right = cv2.imread(str(right_file), cv2.IMREAD_GRAYSCALE)
    sgbm = cv2.StereoSGBM_create(0, 128, 5, 8 * 25, 32 * 25, 1, 63, 10, 100, 2)
    estimate = sgbm.compute(left, right).astype(np.float32) / 16.0
    evaluator = Evaluator(criteria=("all",), missing="ignore")
    good = project_cloud(points, calibration.matrix, left.shape, calibration.camera).disparity
    score = evaluator.score(good, estimate, calibration.camera)["all"]
    assert score["mae"] < 2.0
    assert score["d1"] < 10.0
    # 0.1 m and 2° off: errors explode.
    wrong = matrix_from_pose(
        [0.1, 0.0, 0.0], [0, math.sin(math.radians(1)), 0, math.cos(math.radians(1))]
    )
    bad_matrix = rectified_projection(
        wrong @ calibration.extrinsic, calibration.rectification, calibration.left
    )
    bad = project_cloud(points, bad_matrix, left.shape, calibration.camera).disparity
    bad_score = evaluator.score(bad, estimate, calibration.camera)["all"]
    assert bad_score["d1"] > 3 * score["d1"]
    assert bad_score["mae"] > 2 * score["mae"]
