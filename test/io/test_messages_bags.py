"""Message ↔ numpy conversion and bag I/O, with real rosbags / mcap message objects and files."""

from __future__ import annotations

import dataclasses
import itertools
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rosbags.typesys import Stores, get_typestore

from dispeval_ros.core.camera import Camera
from dispeval_ros.errors import CalibrationError, ConfigurationError, InputError
from dispeval_ros.io.bags import BagSource, BagWriter, TopicInfo, require_topic
from dispeval_ros.io.encoders import camera_info_to_msg, disparity_to_msg, image_to_msg
from dispeval_ros.io.messages import (
    IMAGE_ENCODINGS,
    DisparityFrame,
    ImageFrame,
    camera_from_info_and_baseline,
    camera_from_infos,
    disparity_from_msg,
    gt_disparity,
    image_from_msg,
    stamp_ns,
)

HUMBLE = get_typestore(Stores.ROS2_HUMBLE)
JAZZY = get_typestore(Stores.ROS2_JAZZY)
NOETIC = get_typestore(Stores.ROS1_NOETIC)
STORES = pytest.mark.parametrize("ts", [HUMBLE, JAZZY, NOETIC], ids=["humble", "jazzy", "noetic"])

DISP = "stereo_msgs/msg/DisparityImage"
IMAGE = "sensor_msgs/msg/Image"
INFO = "sensor_msgs/msg/CameraInfo"
T0 = 1_700_000_000_123_456_789
CAM = Camera(700.0, 0.5)
H, W = 12, 20


def disparity_map(seed: int = 0, h: int = H, w: int = W) -> np.ndarray:
    rng = np.random.default_rng(seed)
    disp = rng.uniform(1.0, 120.0, (h, w)).astype(np.float32)
    disp[0, :3] = -1.0  # stereo_image_proc's invalid marker for min_disparity = 0
    return disp


def sample_array(encoding: str, seed: int = 0, h: int = H, w: int = W) -> np.ndarray:
    dtype, channels = IMAGE_ENCODINGS[encoding]
    rng = np.random.default_rng(seed)
    shape = (h, w, channels) if channels > 1 else (h, w)
    if np.issubdtype(dtype, np.floating):
        values = rng.normal(0, 100, shape).astype(dtype)
        values.flat[0] = np.inf
        values.flat[-1] = np.nan if values.size > 1 else values.flat[-1]
        return values
    info = np.iinfo(dtype)
    return rng.integers(0, int(info.max) + 1, shape, dtype=dtype)


def repack(msg, pad: int = 0, bigendian: bool = False):
    """The same Image with ``pad`` bytes of garbage after every row and/or big-endian data."""
    dtype, _ = IMAGE_ENCODINGS[msg.encoding]
    values = np.frombuffer(bytes(msg.data), dtype=np.dtype(dtype).newbyteorder("<"))
    values = values.astype(np.dtype(dtype).newbyteorder(">" if bigendian else "<"))
    rows = values.view(np.uint8).reshape(msg.height, -1)
    padded = np.full((msg.height, rows.shape[1] + pad), 0xAB, dtype=np.uint8)
    padded[:, : rows.shape[1]] = rows
    return dataclasses.replace(
        msg, data=padded.reshape(-1), step=rows.shape[1] + pad, is_bigendian=int(bigendian)
    )


def assert_same(a: np.ndarray, b: np.ndarray) -> None:
    assert a.dtype == b.dtype
    assert a.shape == b.shape
    np.testing.assert_array_equal(a, b)


# -- stamps ---------------------------------------------------------------------------------


@STORES
def test_stamp_ns_of_header_and_time(ts) -> None:
    msg = image_to_msg(ts, np.zeros((2, 2), np.uint8), T0, "cam", "mono8")
    assert stamp_ns(msg.header) == T0
    assert stamp_ns(msg.header.stamp) == T0
    assert msg.header.stamp.sec == T0 // 10**9
    assert msg.header.stamp.nanosec == T0 % 10**9


def test_stamp_ns_rejects_other_objects() -> None:
    with pytest.raises(InputError, match="Header"):
        stamp_ns(object())


# -- DisparityImage -------------------------------------------------------------------------


@STORES
def test_disparity_round_trip_as_stereo_image_proc_publishes(ts) -> None:
    disp = disparity_map()
    msg = disparity_to_msg(ts, disp, T0, "left_optical", 700.0, 0.5, 0.0, 127.0)
    assert msg.image.encoding == "32FC1"
    assert msg.image.step == 4 * W
    assert msg.image.is_bigendian == 0
    assert (msg.image.height, msg.image.width) == (H, W)
    window = msg.valid_window
    assert (window.x_offset, window.y_offset, window.width, window.height) == (0, 0, W, H)
    assert stamp_ns(msg.image.header) == T0
    assert msg.delta_d == pytest.approx(1 / 16)
    ts.serialize_cdr(msg, DISP) if ts is not NOETIC else ts.serialize_ros1(msg, DISP)

    frame = disparity_from_msg(msg, "/stereo/disparity")
    assert isinstance(frame, DisparityFrame)
    assert frame.stamp == T0
    assert frame.frame_id == "left_optical"
    assert_same(frame.disparity, disp)
    assert frame.disparity.flags.c_contiguous
    assert frame.disparity.flags.writeable
    assert frame.disparity[0, 0] == frame.min_disparity - 1  # invalid marker preserved
    assert frame.est_range == (0.0, 127.0)
    assert frame.camera == Camera(700.0, 0.5)
    assert (frame.f, frame.t, frame.delta_d) == (700.0, 0.5, 1 / 16)


@pytest.mark.parametrize(
    "kind", [bytes, bytearray, memoryview, lambda b: np.frombuffer(b, np.uint8), np.asarray]
)
@pytest.mark.parametrize(("pad", "bigendian"), [(0, False), (12, False), (0, True), (6, True)])
def test_disparity_data_container_step_and_endianness(kind, pad, bigendian) -> None:
    disp = disparity_map(1)
    msg = disparity_to_msg(HUMBLE, disp, T0, "c", 700.0, 0.5, 0.0, 127.0)
    image = repack(msg.image, pad, bigendian)
    image = dataclasses.replace(image, data=kind(bytes(image.data)))
    frame = disparity_from_msg(dataclasses.replace(msg, image=image))
    assert_same(frame.disparity, disp)


def test_disparity_valid_window_is_ignored() -> None:
    disp = disparity_map(2)
    msg = disparity_to_msg(HUMBLE, disp, T0, "c", 700.0, 0.5, 0.0, 127.0)
    msg.valid_window.x_offset, msg.valid_window.width = 5, 3
    assert_same(disparity_from_msg(msg).disparity, disp)


@pytest.mark.parametrize(
    ("low", "high", "expected"),
    [
        (0.0, 0.0, (-math.inf, math.inf)),
        (10.0, 5.0, (-math.inf, math.inf)),
        (float("nan"), 5.0, (-math.inf, math.inf)),
        (-16.0, 111.0, (-16.0, 111.0)),
        (0.0, 63.0, (0.0, 63.0)),
    ],
)
def test_est_range(low, high, expected) -> None:
    frame = DisparityFrame(0, "", np.zeros((1, 1), np.float32), 1.0, 1.0, low, high, 1.0)
    assert frame.est_range == expected


@pytest.mark.parametrize(("f", "t"), [(0.0, 0.5), (700.0, 0.0), (math.nan, 1.0)])
def test_disparity_camera_absent_without_f_and_t(f, t) -> None:
    frame = DisparityFrame(0, "", np.zeros((1, 1), np.float32), f, t, 0.0, 1.0, 1.0)
    assert frame.camera is None


def test_disparity_camera_of_a_negative_t_is_its_magnitude() -> None:
    frame = DisparityFrame(0, "", np.zeros((1, 1), np.float32), 700.0, -0.5, 0.0, 1.0, 1.0)
    assert frame.camera == Camera(700.0, 0.5)
    assert frame.negative_t


def test_disparity_wrong_encoding_names_topic_and_encoding() -> None:
    msg = disparity_to_msg(HUMBLE, disparity_map(), T0, "c", 700.0, 0.5, 0.0, 127.0)
    msg.image.encoding = "16UC1"
    with pytest.raises(InputError, match=r"^DisparityImage on /disp: .*'16UC1'.*32FC1$"):
        disparity_from_msg(msg, "/disp")


def test_disparity_short_data_and_bad_step() -> None:
    msg = disparity_to_msg(HUMBLE, disparity_map(), T0, "c", 700.0, 0.5, 0.0, 127.0)
    short = dataclasses.replace(msg.image, data=msg.image.data[:-1])
    with pytest.raises(InputError, match=r"/disp: .*expected height·step"):
        disparity_from_msg(dataclasses.replace(msg, image=short), "/disp")
    narrow = dataclasses.replace(msg.image, step=4 * W - 4)
    with pytest.raises(InputError, match="step"):
        disparity_from_msg(dataclasses.replace(msg, image=narrow), "/disp")
    empty = dataclasses.replace(msg.image, height=0)
    with pytest.raises(InputError, match="empty"):
        disparity_from_msg(dataclasses.replace(msg, image=empty), "/disp")
    with pytest.raises(InputError, match="no field 'image'"):
        disparity_from_msg(msg.image, "/disp")


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    h=st.integers(1, 9),
    w=st.integers(1, 9),
    pad=st.integers(0, 9),
    bigendian=st.booleans(),
    encoding=st.sampled_from(sorted(IMAGE_ENCODINGS)),
)
def test_image_round_trip_property(h, w, pad, bigendian, encoding) -> None:
    array = sample_array(encoding, h * w + pad, h, w)
    msg = repack(image_to_msg(HUMBLE, array, T0, "c", encoding), pad, bigendian)
    assert_same(image_from_msg(msg).array, array)


# -- Image ----------------------------------------------------------------------------------


@pytest.mark.parametrize("encoding", sorted(IMAGE_ENCODINGS))
@pytest.mark.parametrize(("pad", "bigendian"), [(0, False), (5, False), (0, True), (3, True)])
def test_image_round_trip_every_encoding(encoding, pad, bigendian) -> None:
    array = sample_array(encoding)
    msg = image_to_msg(HUMBLE, array, T0, "cam", encoding)
    assert msg.is_bigendian == 0
    assert msg.step == W * array.itemsize * IMAGE_ENCODINGS[encoding][1]
    frame = image_from_msg(repack(msg, pad, bigendian), "/img")
    assert isinstance(frame, ImageFrame)
    assert (frame.stamp, frame.frame_id, frame.encoding) == (T0, "cam", encoding)
    assert_same(frame.array, array)


@pytest.mark.parametrize("ts", [JAZZY, NOETIC], ids=["jazzy", "noetic"])
def test_image_round_trip_other_stores(ts) -> None:
    array = sample_array("16UC1")
    msg = image_to_msg(ts, array, T0, "cam", "mono16")
    assert_same(image_from_msg(msg).array, array)


def test_image_unsupported_encoding_lists_supported() -> None:
    msg = image_to_msg(HUMBLE, np.zeros((2, 2), np.uint8), T0, "c", "mono8")
    msg.encoding = "yuv422"
    with pytest.raises(InputError, match=r"^Image on /cam: .*'yuv422'.*32FC1, 64FC1, 16UC1"):
        image_from_msg(msg, "/cam")


def test_image_to_msg_rejects_bad_input() -> None:
    with pytest.raises(ConfigurationError, match="not supported"):
        image_to_msg(HUMBLE, np.zeros((2, 2)), T0, "c", "jpeg")
    with pytest.raises(ConfigurationError, match="H×W×3"):
        image_to_msg(HUMBLE, np.zeros((2, 2), np.uint8), T0, "c", "rgb8")
    with pytest.raises(ConfigurationError, match="in \\[0, 65535\\]"):
        image_to_msg(HUMBLE, np.full((2, 2), 70000), T0, "c", "16UC1")
    with pytest.raises(ConfigurationError, match="integer"):
        image_to_msg(HUMBLE, np.zeros((2, 2)), T0, "c", "mono8")


# -- ground truth ---------------------------------------------------------------------------


def gt_frame(array: np.ndarray, encoding: str) -> ImageFrame:
    return image_from_msg(image_to_msg(HUMBLE, array, T0, "c", encoding))


def test_gt_disparity_float_as_is_and_16bit_kitti_scale() -> None:
    values = np.array([[0.0, 12.5, np.inf]], np.float32)
    assert_same(gt_disparity(gt_frame(values, "32FC1")), values)
    assert_same(gt_disparity(gt_frame(values.astype(np.float64), "64FC1")), values)
    raw = np.array([[0, 256, 3200, 65535]], np.uint16)
    expected = np.array([[0.0, 1.0, 12.5, 65535 / 256]], np.float32)
    assert_same(gt_disparity(gt_frame(raw, "16UC1")), expected)
    assert_same(gt_disparity(gt_frame(raw, "mono16"), scale=64.0), raw.astype(np.float32) / 64)


def test_gt_depth_hand_worked() -> None:
    # f = 700 px, B = 0.5 m, Z = 10 m  →  d = 700 · 0.5 / 10 = 35 px
    metres = np.array([[10.0, 0.0, -1.0, np.nan, np.inf, 35.0]], np.float32)
    expected = np.array([[35.0, 0.0, 0.0, 0.0, 0.0, 10.0]], np.float32)
    assert_same(gt_disparity(gt_frame(metres, "32FC1"), "depth", camera=CAM), expected)
    millimetres = np.array([[10000, 0, 35000]], np.uint16)
    assert_same(
        gt_disparity(gt_frame(millimetres, "16UC1"), "depth", camera=CAM),
        np.array([[35.0, 0.0, 10.0]], np.float32),
    )
    with_doffs = Camera(700.0, 0.5, doffs=5.0)
    assert gt_disparity(gt_frame(metres, "32FC1"), "depth", camera=with_doffs)[0, 0] == 30.0
    in_mm = Camera(700.0, 500.0, unit="mm")
    assert gt_disparity(gt_frame(metres, "32FC1"), "depth", camera=in_mm)[0, 0] == 35.0


def test_gt_errors() -> None:
    depth = gt_frame(np.ones((2, 2), np.float32), "32FC1")
    with pytest.raises(CalibrationError, match=r"^ground-truth Image on /gt: depth .*camera"):
        gt_disparity(depth, "depth", topic="/gt")
    with pytest.raises(ConfigurationError, match="kind"):
        gt_disparity(depth, "height")
    with pytest.raises(ConfigurationError, match="scale"):
        gt_disparity(depth, scale=0.0)
    with pytest.raises(InputError, match=r"/gt: .*'mono8'.*32FC1"):
        gt_disparity(gt_frame(np.ones((2, 2), np.uint8), "mono8"), topic="/gt")
    with pytest.raises(InputError, match="'rgb8'"):
        gt_disparity(gt_frame(np.ones((2, 2, 3), np.uint8), "rgb8"))


# -- CameraInfo -----------------------------------------------------------------------------


def info_pair(ts, camera: Camera = CAM, cx: float | None = None):
    left = camera_info_to_msg(ts, camera, W, H, T0, "left", right=False, cx=cx)
    right = camera_info_to_msg(ts, camera, W, H, T0, "right", right=True, cx=cx)
    return left, right


@STORES
def test_camera_from_infos_ros2_and_ros1_field_names(ts) -> None:
    left, right = info_pair(ts, Camera(721.5, 0.54, doffs=2.5), cx=600.0)
    fields = ("p", "k", "d") if ts is not NOETIC else ("P", "K", "D")
    assert all(hasattr(right, name) for name in fields)
    assert right.distortion_model == "plumb_bob"
    p_right = np.asarray(getattr(right, fields[0]))
    assert p_right[3] == pytest.approx(-721.5 * 0.54)
    assert p_right[2] == 602.5
    camera = camera_from_infos(left, right, "/left/info", "/right/info")
    assert camera.f == 721.5
    assert camera.baseline == pytest.approx(0.54)
    assert camera.doffs == pytest.approx(2.5)


def test_camera_info_default_principal_point() -> None:
    left, _ = info_pair(HUMBLE)
    assert left.k[2] == W / 2 - 0.5
    assert left.k[5] == H / 2 - 0.5
    assert np.array_equal(left.r, np.eye(3).reshape(-1))
    assert left.p[3] == 0


def test_camera_from_infos_errors_name_the_topic() -> None:
    left, right = info_pair(HUMBLE)
    with pytest.raises(
        CalibrationError,
        match=r"^CameraInfo on /right/info has P\[3\] = 0: zero baseline; is this the right",
    ):
        camera_from_infos(left, left, "/left/info", "/right/info")
    with pytest.raises(CalibrationError, match=r"/left/info.*swapped"):
        camera_from_infos(right, left, "/right/info", "/left/info")
    uncalibrated = dataclasses.replace(left, p=np.zeros(12))
    with pytest.raises(CalibrationError, match=r"^CameraInfo on /left/info has P\[0\] = 0"):
        camera_from_infos(uncalibrated, right, "/left/info", "/right/info")
    other_f = camera_info_to_msg(HUMBLE, Camera(500.0, 0.5), W, H, T0, "r", right=True)
    with pytest.raises(CalibrationError, match="not a rectified stereo pair"):
        camera_from_infos(left, other_f, "/left/info", "/right/info")
    broken = right.p.copy()
    broken[3] = np.nan
    with pytest.raises(CalibrationError, match="P\\[3\\] = nan"):
        camera_from_infos(left, dataclasses.replace(right, p=broken))


def test_camera_from_info_and_baseline() -> None:
    left, _ = info_pair(HUMBLE)
    assert camera_from_info_and_baseline(left, 0.12) == Camera(700.0, 0.12)
    with pytest.raises(CalibrationError, match="/left/info"):
        camera_from_info_and_baseline(left, 0.0, "/left/info")


# -- bags -----------------------------------------------------------------------------------

FORMATS = ["rosbag2-sqlite3", "rosbag2-mcap", "mcap"]
N = 8
STEP = 100_000_000


def bag_path(tmp_path: Path, fmt: str) -> Path:
    return tmp_path / ("bag.mcap" if fmt == "mcap" else "bag")


def write_bag(path: Path, fmt: str) -> None:
    left, right = info_pair(HUMBLE)
    with BagWriter(path, fmt) as writer:
        writer.add_topic("/disp", DISP)
        writer.add_topic("/gt", IMAGE)
        writer.add_topic("/left/info", INFO)
        writer.add_topic("/right/info", "sensor_msgs/CameraInfo")
        for i in range(N):
            stamp = T0 + i * STEP
            writer.write("/left/info", stamp, left)
            writer.write("/right/info", stamp, right)
            gt = (disparity_map(100 + i) * 256).astype(np.uint16)
            writer.write("/gt", stamp + 1, image_to_msg(HUMBLE, gt, stamp, "cam", "16UC1"))
            disp = disparity_map(i)
            writer.write(
                "/disp", stamp + 2, disparity_to_msg(HUMBLE, disp, stamp, "cam", 700, 0.5, 0, 127)
            )


@pytest.fixture(scope="module", params=FORMATS)
def written_bag(request, tmp_path_factory) -> tuple[str, Path]:
    fmt = request.param
    path = bag_path(tmp_path_factory.mktemp(fmt), fmt)
    write_bag(path, fmt)
    return fmt, path


def test_bag_round_trip(written_bag) -> None:
    fmt, path = written_bag
    with BagSource(path) as source:
        assert source.format == fmt
        assert source.path == path
        assert source.topics == {
            "/disp": TopicInfo("/disp", DISP, N),
            "/gt": TopicInfo("/gt", IMAGE, N),
            "/left/info": TopicInfo("/left/info", INFO, N),
            "/right/info": TopicInfo("/right/info", INFO, N),
        }
        assert source.message_count == 4 * N
        assert source.start_ns == T0
        assert source.end_ns == T0 + (N - 1) * STEP + 3
        items = list(source.messages(["/disp", "/gt", "/left/info", "/right/info"]))
    times = [log for _, log, _ in items]
    assert times == sorted(times)
    assert len(items) == 4 * N
    disps = [(log, msg) for topic, log, msg in items if topic == "/disp"]
    for i, (log, msg) in enumerate(disps):
        frame = disparity_from_msg(msg, "/disp")
        assert log == T0 + i * STEP + 2
        assert frame.stamp == T0 + i * STEP
        assert_same(frame.disparity, disparity_map(i))
        assert frame.est_range == (0.0, 127.0)
        assert frame.camera == CAM
    gts = [msg for topic, _, msg in items if topic == "/gt"]
    for i, msg in enumerate(gts):
        expected = (disparity_map(100 + i) * 256).astype(np.uint16)
        assert_same(image_from_msg(msg, "/gt").array, expected)
        assert_same(gt_disparity(image_from_msg(msg)), expected.astype(np.float32) / 256)
    infos = {topic: msg for topic, _, msg in items if topic.endswith("info")}
    assert camera_from_infos(infos["/left/info"], infos["/right/info"]) == CAM


def test_rosbag2_metadata_is_version_8(written_bag) -> None:
    fmt, path = written_bag
    if fmt == "mcap":
        from mcap.reader import make_reader

        with path.open("rb") as file:
            reader = make_reader(file)
            assert reader.get_header().profile == "ros2"
            summary = reader.get_summary()
            assert summary is not None
            assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
        return
    text = (path / "metadata.yaml").read_text()
    assert "version: 8" in text
    storage = "mcap" if fmt == "rosbag2-mcap" else "sqlite3"
    assert f"storage_identifier: {storage}" in text
    # Opening the storage file inside the folder opens the folder.
    (storage_file,) = path.glob("*.mcap" if storage == "mcap" else "*.db3")
    with BagSource(storage_file) as source:
        assert source.format == fmt
        assert source.message_count == 4 * N


def test_bag_time_window(written_bag) -> None:
    _, path = written_bag
    with BagSource(path) as source:
        start, stop = T0 + 2 * STEP, T0 + 5 * STEP + 2  # stop excludes the /disp at +2
        got = [(topic, log) for topic, log, _ in source.messages(["/disp"], start, stop)]
        assert got == [("/disp", T0 + i * STEP + 2) for i in (2, 3, 4)]
        assert list(source.messages(["/gt"], stop_ns=T0 + 1)) == []
        assert len(list(source.messages("/gt", start_ns=T0 + (N - 1) * STEP + 1))) == 1


def test_require_topic(written_bag) -> None:
    _, path = written_bag
    with BagSource(path) as source:
        assert require_topic(source, "/disp", [DISP]) == TopicInfo("/disp", DISP, N)
        assert require_topic(source, "/gt", ["sensor_msgs/Image"]).count == N
        with pytest.raises(InputError) as missing:
            require_topic(source, "/nope", [DISP])
        text = str(missing.value)
        assert text.startswith(f"{path} has no topic /nope; topics: ")
        assert f"/disp ({DISP}, {N} msgs)" in text
        assert f"/right/info ({INFO}, {N} msgs)" in text
        assert "\n" not in text
        with pytest.raises(InputError, match=f"/gt has type {IMAGE}, expected {DISP}"):
            require_topic(source, "/gt", [DISP])
        with pytest.raises(InputError, match="no topic /nope"):
            source.messages(["/nope"])


def test_ros1_bag_written_by_rosbags(tmp_path) -> None:
    from rosbags.rosbag1 import Writer

    path = tmp_path / "old.bag"
    left, right = info_pair(NOETIC)
    with Writer(path) as writer:
        conn_disp = writer.add_connection("/disp", DISP, typestore=NOETIC)
        conn_info = writer.add_connection("/right/info", INFO, typestore=NOETIC)
        conn_left = writer.add_connection("/left/info", INFO, typestore=NOETIC)
        for i in range(N):
            stamp = T0 + i * STEP
            msg = disparity_to_msg(NOETIC, disparity_map(i), stamp, "cam", 700, 0.5, 0, 127)
            writer.write(conn_disp, stamp, NOETIC.serialize_ros1(msg, DISP))
            writer.write(conn_info, stamp, NOETIC.serialize_ros1(right, INFO))
            writer.write(conn_left, stamp, NOETIC.serialize_ros1(left, INFO))
    with BagSource(path) as source:
        assert source.format == "ros1"
        assert source.topics["/disp"] == TopicInfo("/disp", DISP, N)
        assert source.topics["/right/info"].msgtype == INFO
        items = list(source.messages(["/disp", "/left/info", "/right/info"], T0 + STEP))
    assert len(items) == 3 * (N - 1)
    disps = [msg for topic, _, msg in items if topic == "/disp"]
    assert hasattr(disps[0], "T")
    assert not hasattr(disps[0], "t")
    frame = disparity_from_msg(disps[0], "/disp")
    assert frame.stamp == T0 + STEP
    assert frame.camera == CAM
    assert_same(frame.disparity, disparity_map(1))
    infos = {topic: msg for topic, _, msg in items if topic.endswith("info")}
    assert camera_from_infos(infos["/left/info"], infos["/right/info"]) == CAM


def test_bag_writer_refuses_existing_output_and_unknown_format(tmp_path) -> None:
    (tmp_path / "taken").mkdir()
    with pytest.raises(InputError, match="taken exists; remove it or choose another path"):
        BagWriter(tmp_path / "taken")
    with pytest.raises(ConfigurationError, match="rosbag2-sqlite3, rosbag2-mcap, mcap"):
        BagWriter(tmp_path / "new", "ros3")


@pytest.mark.parametrize("fmt", FORMATS)
def test_bag_writer_topics(tmp_path, fmt) -> None:
    path = bag_path(tmp_path, fmt)
    msg = image_to_msg(HUMBLE, np.zeros((2, 3), np.uint8), T0, "c", "mono8")
    with BagWriter(path, fmt) as writer:
        writer.write("/auto", T0, msg)  # added from the message's type
        writer.add_topic("/auto", IMAGE)  # repeating is a no-op
        with pytest.raises(ConfigurationError, match="/auto was added as"):
            writer.add_topic("/auto", DISP)
        with pytest.raises(ConfigurationError, match="add topic /plain"):
            writer.write("/plain", T0, object())
        with pytest.raises(ConfigurationError, match="no message type"):
            writer.add_topic("/x", "pkg/msg/Nothing")
    with BagSource(path) as source:
        assert source.topics == {"/auto": TopicInfo("/auto", IMAGE, 1)}


def test_unordered_mcap_comes_out_in_log_time_order(tmp_path) -> None:
    path = tmp_path / "unordered.mcap"
    order = [5, 1, 4, 2, 3, 0]
    with BagWriter(path, "mcap") as writer:
        for i in order:
            msg = image_to_msg(HUMBLE, np.full((2, 2), i, np.uint8), T0 + i, "c", "mono8")
            writer.write("/img", T0 + i, msg)
    with BagSource(path) as source:
        assert [log - T0 for _, log, _ in source.messages(["/img"])] == sorted(order)
    # Without its summary (cut before the footer) the file is scanned, then sorted.
    cut = tmp_path / "cut.mcap"
    data = path.read_bytes()
    cut.write_bytes(data[: data.rfind(b"\x89MCAP0\r\n") - 1])
    with BagSource(cut) as source:
        got = []
        with pytest.raises(InputError, match="truncated"):
            got.extend(source.messages(["/img"]))
        assert [log - T0 for _, log, _ in got] == sorted(order)


# -- damaged bags ---------------------------------------------------------------------------


def truncate(file: Path, fraction: float) -> None:
    data = file.read_bytes()
    file.write_bytes(data[: int(len(data) * fraction)])


@pytest.fixture(scope="module")
def pristine(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("pristine")
    paths = {}
    for fmt in FORMATS:
        paths[fmt] = bag_path(root / fmt, fmt)
        paths[fmt].parent.mkdir()
        write_bag(paths[fmt], fmt)
    return paths


def copy_bag(pristine: dict[str, Path], fmt: str, tmp_path: Path) -> Path:
    source = pristine[fmt]
    tmp_path.mkdir(parents=True, exist_ok=True)
    target = tmp_path / source.name
    if source.is_dir():
        shutil.copytree(source, target)
    else:
        shutil.copy(source, target)
    return target


def read_everything(path: Path) -> list[tuple[str, int]]:
    with BagSource(path) as source:
        return [(topic, log) for topic, log, _ in source.messages(list(source.topics))]


@pytest.mark.parametrize("fraction", [0.5, 0.97])
def test_truncated_sqlite_bag(pristine, tmp_path, fraction) -> None:
    path = copy_bag(pristine, "rosbag2-sqlite3", tmp_path)
    truncate(next(path.glob("*.db3")), fraction)
    with pytest.raises(InputError, match=f"^{path}: "):
        read_everything(path)


@pytest.mark.parametrize("fmt", ["rosbag2-mcap", "mcap"])
@pytest.mark.parametrize("fraction", [0.5, 0.97])
def test_truncated_mcap_yields_messages_before_the_damage(tmp_path, fmt, fraction):
    # 0.5 MB messages: the 1 MB chunks of both writers hold two each, so a cut loses one chunk
    # (uncompressed: constant images would fit many to a compressed chunk).
    path = bag_path(tmp_path, fmt)
    count = 12
    with BagWriter(path, fmt, compress=False) as writer:
        for i in range(count):
            array = np.full((512, 512), i, np.uint16)
            writer.write("/img", T0 + i, image_to_msg(HUMBLE, array, T0 + i, "c", "16UC1"))
    truncate(next(path.glob("*.mcap")) if path.is_dir() else path, fraction)
    got: list[tuple[int, int]] = []
    with BagSource(path) as source:
        assert source.format == fmt
        assert 0 < source.message_count < count
        with pytest.raises(
            InputError, match=rf"^{path}: MCAP file is truncated .* after \d+ messages"
        ):
            got.extend(
                (log - T0, int(image_from_msg(msg).array[0, 0]))
                for _, log, msg in source.messages(["/img"])
            )
    assert got == [(i, i) for i in range(source.message_count)]


def test_truncated_ros1_bag(tmp_path) -> None:
    from rosbags.rosbag1 import Writer

    path = tmp_path / "cut.bag"
    with Writer(path) as writer:
        conn = writer.add_connection("/img", IMAGE, typestore=NOETIC)
        for i in range(N):
            msg = image_to_msg(NOETIC, np.full((H, W), i, np.uint8), T0 + i, "c", "mono8")
            writer.write(conn, T0 + i, NOETIC.serialize_ros1(msg, IMAGE))
    truncate(path, 0.6)
    with pytest.raises(InputError, match=f"^{path}: "):
        read_everything(path)


@pytest.mark.parametrize(
    ("name", "content"),
    [
        ("junk.mcap", b"not an mcap file at all"),
        ("junk.db3", b"not a database" * 100),
        ("junk.bag", b"#ROSBAG V2.0\n garbage"),
        ("empty.mcap", b""),
        ("notes.txt", b"hello"),
    ],
)
def test_corrupt_files(tmp_path, name, content) -> None:
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(InputError, match=f"^{path}: ") as error:
        read_everything(path)
    assert "\n" not in str(error.value)


@pytest.mark.parametrize("fmt", ["rosbag2-sqlite3", "rosbag2-mcap"])
def test_garbage_metadata_and_missing_paths(pristine, tmp_path, fmt) -> None:
    path = copy_bag(pristine, fmt, tmp_path)
    (path / "metadata.yaml").write_text("{{{ this: is [not yaml")
    with pytest.raises(InputError, match=f"^{path}: cannot read bag"):
        BagSource(path)
    (path / "metadata.yaml").write_text("rosbag2_bagfile_information: 3\n")
    with pytest.raises(InputError, match=f"^{path}: cannot read bag"):
        BagSource(path)
    with pytest.raises(InputError, match="not found"):
        BagSource(tmp_path / "nothing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="empty: not a bag"):
        BagSource(tmp_path / "empty")


def test_storage_files_without_metadata(pristine, tmp_path) -> None:
    """A lone .db3 is read by rosbags; a folder with one bag file and no metadata opens it."""
    lone = tmp_path / "lone.db3"
    shutil.copy(next(pristine["rosbag2-sqlite3"].glob("*.db3")), lone)
    with BagSource(lone) as source:
        assert source.format == "rosbag2-sqlite3"
        assert source.topics["/disp"] == TopicInfo("/disp", DISP, N)
    folder = tmp_path / "folder"
    folder.mkdir()
    shutil.copy(pristine["mcap"], folder / "recording.mcap")
    with BagSource(folder) as source:
        assert source.format == "mcap"
        assert source.message_count == 4 * N
    shutil.copy(lone, folder / "other.db3")
    with pytest.raises(InputError, match="several bag files"):
        BagSource(folder)


def test_interleaved_iterations_of_a_scanned_mcap(pristine, tmp_path) -> None:
    path = copy_bag(pristine, "mcap", tmp_path)
    data = path.read_bytes()
    path.write_bytes(data[: data.rfind(b"\x89MCAP0\r\n") - 1])  # keep the data, lose the footer
    with BagSource(path) as source:
        first = source.messages(["/disp"])
        second = source.messages(["/gt"])
        pairs = list(zip(itertools.islice(first, N), itertools.islice(second, N), strict=True))
        with pytest.raises(InputError, match="truncated"):
            next(first)
    assert [(a[0], b[0]) for a, b in pairs] == [("/disp", "/gt")] * N
    assert [a[1] - b[1] for a, b in pairs] == [1] * N


def test_message_that_does_not_deserialize(tmp_path) -> None:
    """A bad message raises InputError naming topic and log time, or goes to on_error."""
    from rosbags.rosbag2 import Writer

    path = tmp_path / "bad"
    good = HUMBLE.serialize_cdr(
        image_to_msg(HUMBLE, np.zeros((H, W), np.uint8), T0, "c", "mono8"), IMAGE
    )
    with Writer(path, version=8) as writer:
        conn = writer.add_connection("/img", IMAGE, typestore=HUMBLE)
        for i in range(4):
            writer.write(conn, T0 + i, good if i != 2 else bytes(good)[:30])
    with BagSource(path) as source:
        got: list[int] = []
        with pytest.raises(InputError, match=f"on /img at log time {T0 + 2} ns"):
            got.extend(log for _, log, _ in source.messages(["/img"]))
        assert got == [T0, T0 + 1]
        problems: list[InputError] = []
        logs = [log for _, log, _ in source.messages(["/img"], on_error=problems.append)]
        assert logs == [T0, T0 + 1, T0 + 3]
        assert len(problems) == 1

    from mcap.writer import Writer as McapWriter

    plain = tmp_path / "bad.mcap"
    with plain.open("wb") as file:
        mcap = McapWriter(file)
        mcap.start(profile="ros2")
        msgdef = HUMBLE.generate_msgdef(IMAGE, ros_version=2)[0].encode()
        channel = mcap.register_channel(
            "/img", "cdr", mcap.register_schema(IMAGE, "ros2msg", msgdef)
        )
        for i in range(4):
            data = bytes(good) if i != 1 else bytes(good)[:30]
            mcap.add_message(channel, T0 + i, data, T0 + i)
        mcap.finish()
    with BagSource(plain) as source:
        assert source.format == "mcap"
        with pytest.raises(InputError, match=f"on /img at log time {T0 + 1} ns"):
            list(source.messages(["/img"]))
        problems = []
        assert len(list(source.messages(["/img"], on_error=problems.append))) == 3
        assert len(problems) == 1


def test_plain_mcap_checks_chunk_crcs(pristine, tmp_path) -> None:
    path = copy_bag(pristine, "mcap", tmp_path)
    data = bytearray(path.read_bytes())
    middle = len(data) // 3
    data[middle : middle + 8] = b"\xff" * 8
    path.write_bytes(bytes(data))
    with pytest.raises(InputError, match=f"^{path}: MCAP file is damaged.*crc"):
        read_everything(path)


DETECTS_EVERY_SCRIBBLE = ("mcap",)
"""Formats whose reader checks every byte it reads (plain MCAP: chunk CRCs); the others hold
payload bytes no checksum covers, so some damage reads as other values."""


@pytest.mark.parametrize("fmt", FORMATS)
def test_scribbled_storage_raises_only_input_errors(pristine, tmp_path, fmt) -> None:
    """Garbage written anywhere: the bag reads (undetectable damage) or raises InputError.

    The damage must be found where it can be: every scribble in a CRC-checked format, and at
    least one of the twelve (seeded) scribbles in the others, so a reader that accepts
    everything fails here.
    """
    rng = np.random.default_rng(7)
    messages: list[str] = []
    for trial in range(12):
        path = copy_bag(pristine, fmt, tmp_path / str(trial))
        storage = path if path.is_file() else next(path.glob("*.[dm][bc]*"))
        data = bytearray(storage.read_bytes())
        start = int(rng.integers(0, len(data)))
        size = int(rng.choice([1, 16, 512]))
        data[start : start + size] = rng.bytes(len(data[start : start + size]))
        storage.write_bytes(bytes(data))
        try:
            read_everything(path)
        except InputError as error:
            messages.append(str(error).replace(str(path), "BAG", 1))
    assert all(message.startswith("BAG: ") for message in messages), messages  # names the bag
    assert all("\n" not in message for message in messages)
    if fmt in DETECTS_EVERY_SCRIBBLE:
        assert len(messages) == 12, f"{12 - len(messages)} scribbles read without an error"
    else:
        assert messages, "no scribble was detected"


@pytest.mark.parametrize("fmt", FORMATS)
def test_scribbled_file_header_is_an_input_error(pristine, tmp_path, fmt) -> None:
    """The storage file's first 64 bytes (its magic) overwritten: no format reads that."""
    path = copy_bag(pristine, fmt, tmp_path)
    storage = path if path.is_file() else next(path.glob("*.[dm][bc]*"))
    data = bytearray(storage.read_bytes())
    data[:64] = b"\xa5" * 64
    storage.write_bytes(bytes(data))
    with pytest.raises(InputError, match=f"^{path}: cannot read bag") as error:
        read_everything(path)
    assert "\n" not in str(error.value)
