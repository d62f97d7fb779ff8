"""Write test-bed bags: rectified stereo, CameraInfo, exact GT and real stereo methods' output.

Every method's output is published as a ``stereo_msgs/DisparityImage`` exactly as ROS 2
stereo_image_proc does (32FC1, ``f``, ``t``, ``min/max_disparity``, ``delta_d = 1/16``,
invalid pixels = ``min_disparity − 1``, values and range offset-corrected by the camera's
``doffs`` as the message defines, the images' header); the ground truth is an Image of the
dataset's own ``x_l − x_r`` (the CameraInfo pair carries ``doffs``). Methods are logged a
little after the images as a real pipeline would (each method has its own processing latency),
so the bag exercises the stamp join the same way a recording of a robot does. A KITTI raw drive
(:func:`kitti_raw_frames`) keeps its recorded stamps, stream by stream, and has no GT map;
``--est`` maps (:class:`Estimates`) are published beside the methods.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from dispeval_ros.core import Camera
from dispeval_ros.core.projection import CloudFilter, project_cloud
from dispeval_ros.core.transforms import StaticTransform, invert_rigid, matrix_from_pose
from dispeval_ros.errors import ConfigurationError, InputError, ShapeMismatchError
from dispeval_ros.io.bags import BagWriter
from dispeval_ros.io.encoders import (
    camera_info_to_msg,
    cloud_to_msg,
    disparity_to_msg,
    image_to_msg,
    tf_static_to_msg,
)
from dispeval_ros.io.files import read_disparity
from dispeval_ros.io.scenes import list_frames
from dispeval_ros.stream.core import CoreConfig
from dispeval_ros.testbed import StereoFrame, StereoMethod, default_methods, make_driving_sequence
from dispeval_ros.testbed.lidar import LidarModel, lidar_to_camera, rig_motion, simulate_scan
from dispeval_ros.testbed.methods import left_right_confidence
from dispeval_ros.testbed.scene import driving_setup, driving_world_at

LEFT_IMAGE = "/stereo/left/image_rect"
RIGHT_IMAGE = "/stereo/right/image_rect"
LEFT_INFO = "/stereo/left/camera_info"
RIGHT_INFO = "/stereo/right/camera_info"
GT_TOPIC = "/stereo/ground_truth/disparity"
CLOUD_TOPIC = "/lidar/points"
TF_STATIC_TOPIC = "/tf_static"
TF_TOPIC = "/tf"
ODOM_FRAME = "odom"
CAMERA_FRAME = "stereo_left"
LIDAR_FRAME = "velodyne"
BASE_FRAME = "base_link"
#: Where the LiDAR sits on the vehicle (base_link: x forward, y left, z up, on the ground).
LIDAR_MOUNT = matrix_from_pose([0.0, 0.0, 2.05], [0.0, 0.0, 0.0, 1.0])
START_NS = 1_700_000_000_000_000_000
"""Stamp of the first frame (a fixed date, so bags are byte-for-byte reproducible)."""


def disparity_topic(method: str) -> str:
    """Where a method's DisparityImage goes."""
    return f"/stereo/{method}/disparity"


def confidence_topic(method: str) -> str:
    """Where a method's confidence map goes (``--confidence``: mono8, higher is better)."""
    return f"/stereo/{method}/confidence"


CONFIDENCE_PRESET = "higher"
"""The convention of the confidences make-bag writes (mono8, 0–255, higher is better)."""


@dataclass(frozen=True)
class StreamStamps:
    """Recorded header stamps (ns since the epoch) of a frame's streams, each its own."""

    left: int
    right: int
    cloud: int
    odometry: int


@dataclass(frozen=True)
class BagFrame:
    """What one frame of a test-bed bag holds; ``camera`` is None for uncalibrated scenes."""

    left: np.ndarray
    right: np.ndarray
    gt: np.ndarray | None
    """The exact GT disparity, or None (a recording whose reference is its LiDAR)."""
    camera: Camera | None
    stamp: float
    cloud: np.ndarray | None = None
    """A LiDAR scan (N×3, the LiDAR's frame) taken at ``stamp``, or None."""
    cloud_to_camera: np.ndarray | None = None
    """The LiDAR → left optical frame transform (4×4) of ``cloud``."""
    principal: tuple[float, float] | None = None
    """The left camera's ``(cx, cy)`` in px (default: the image centre)."""
    stamps: StreamStamps | None = None
    """Recorded stamps, used instead of ``START_NS + stamp`` for every stream."""
    odometry: np.ndarray | None = None
    """odom → base_link (4×4) at ``stamps.odometry``: the vehicle's ego-motion, on /tf."""
    lidar_mount: np.ndarray | None = None
    """base_link → LiDAR (4×4) of a real vehicle (default :data:`LIDAR_MOUNT`)."""
    camera_mount: np.ndarray | None = None
    """base_link → left optical (4×4) on /tf_static for a frame with ``odometry`` but no scan
    (with a scan, :func:`static_transforms` derives it from ``cloud_to_camera``)."""
    number: int | None = None
    """The frame's number in its source's file names (``--est`` files are named by it)."""
    gt_source: str = ""
    """What the GT is when it is not a measured map (e.g. a projected LiDAR scan)."""


def static_transforms(
    cloud_to_camera: np.ndarray, mount: np.ndarray = LIDAR_MOUNT
) -> list[StaticTransform]:
    """/tf_static of a vehicle: base_link → LiDAR (``mount``) and base_link → left optical."""
    camera_pose = mount @ invert_rigid(cloud_to_camera)
    return [
        StaticTransform(BASE_FRAME, LIDAR_FRAME, mount),
        StaticTransform(BASE_FRAME, CAMERA_FRAME, camera_pose),
    ]


def _mount_edges(frame: BagFrame, stamps: StreamStamps) -> tuple[list[StaticTransform], int] | None:
    """/tf_static of a frame with a scan or a camera mount, and its stamp (before its users)."""
    if frame.cloud is not None and frame.cloud_to_camera is not None:
        mount = LIDAR_MOUNT if frame.lidar_mount is None else frame.lidar_mount
        return static_transforms(frame.cloud_to_camera, mount), min(stamps.left, stamps.cloud)
    if frame.camera_mount is not None:
        edges = [StaticTransform(BASE_FRAME, CAMERA_FRAME, frame.camera_mount)]
        return edges, min(stamps.left, stamps.odometry)
    return None


def bag_config(methods: Sequence[str]) -> CoreConfig:
    """What ``dispeval bag`` needs to read these methods from a bag :func:`write_bag` wrote."""
    return CoreConfig(
        methods={name: disparity_topic(name) for name in methods},
        gt_topic=GT_TOPIC,
        left_info_topic=LEFT_INFO,
        right_info_topic=RIGHT_INFO,
    )


#: Extensions of ``--est`` files (16-bit PNG is value / 256, as KITTI's).
EST_SUFFIXES = (".png", ".pfm", ".npy")
_EST_FILE = re.compile(r"^(\d+)\.(png|pfm|npy)$", re.IGNORECASE)


LIDAR_GT_SOURCE = (
    f"the LiDAR scan projected into the left camera (parallax filter {CloudFilter()}), "
    "not a measured dense map"
)
"""What the GT of a ``kitti-lidar`` scene is (``load_scene`` projects its scan)."""


def _grey_pair(folder: Path, left: Path, right: Path) -> tuple[np.ndarray, np.ndarray]:
    """Both images of a frame as 8-bit grey: what the OpenCV methods match and the bag holds."""
    left_image = cv2.imread(str(left), cv2.IMREAD_GRAYSCALE)
    right_image = cv2.imread(str(right), cv2.IMREAD_GRAYSCALE)
    if left_image is None or right_image is None:
        raise InputError(f"{folder}: cannot read the images {left.name}, {right.name}")
    if left_image.shape != right_image.shape:
        raise InputError(
            f"{folder}: {left.name} is {left_image.shape[1]}×{left_image.shape[0]} but "
            f"{right.name} is {right_image.shape[1]}×{right_image.shape[0]}"
        )
    return left_image, right_image


def _frame_number(folder: Path, name: str, index: int) -> int:
    """A scene frame's number: the digits after ``FOLDER_`` of its name, else its position."""
    prefix = folder.name + "_"
    suffix = name[len(prefix) :] if name.startswith(prefix) else ""
    return int(suffix) if suffix.isdigit() else index


def dataset_frames(folder: Path) -> Iterator[BagFrame]:
    """Frames of a dataset scene folder (any layout ``load_scene`` reads, or a KITTI raw drive)."""
    from dispeval_ros.io.kitti_raw import is_raw_source

    if is_raw_source(folder):
        yield from kitti_raw_frames(folder)
        return
    for index, scene in enumerate(list_frames(folder)):
        if scene.left is None or scene.right is None:
            raise InputError(
                f"{folder}: the scene has no left/right images to run stereo methods on"
            )
        left, right = _grey_pair(folder, scene.left, scene.right)
        if left.shape != scene.gt.shape:
            raise InputError(
                f"{folder}: images are {left.shape} and {right.shape} but the GT is {scene.gt.shape}"
            )
        cloud = extrinsic = principal = None
        gt_source = ""
        if scene.lidar is not None and scene.lidar_calib is not None:
            from dispeval_ros.io.lidar import read_lidar_calib, read_velodyne_bin

            cloud = read_velodyne_bin(scene.lidar)
            extrinsic, cx, cy = read_lidar_calib(scene.lidar_calib).ros_view()
            principal = (cx, cy)
            gt_source = LIDAR_GT_SOURCE
        yield BagFrame(
            left,
            right,
            scene.gt.astype(np.float32),
            scene.camera,
            float(index),
            cloud,
            extrinsic,
            principal,
            number=_frame_number(folder, scene.name, index),
            gt_source=gt_source,
        )


def kitti_raw_frames(folder: Path) -> Iterator[BagFrame]:
    """Frames of a KITTI raw drive (or of a day folder's only drive): no GT map.

    Both images, the scan and the oxts pose keep their own recorded stamps; the camera and
    the LiDAR → camera transform are the ROS view of ``P_rect_02/03``, ``R_rect_00`` and
    ``calib_velo_to_cam`` (as for ``kitti-lidar``), the LiDAR mount is ``calib_imu_to_velo``
    inverted, so base_link is the oxts unit, the frame of the poses on /tf.
    """
    from dispeval_ros.io.kitti_raw import STREAMS, open_drive, oxts_poses, read_oxts
    from dispeval_ros.io.lidar import read_velodyne_bin

    drive = open_drive(folder)
    left_stream, right_stream, scans, oxts = (drive.streams[name] for name in STREAMS)
    poses = oxts_poses(np.stack([read_oxts(file) for file in oxts.files]))
    extrinsic, cx, cy = drive.calibration.ros_view()
    camera = drive.calibration.camera
    mount = invert_rigid(drive.imu_to_velo)
    first_shape: tuple[int, ...] | None = None
    for index, number in enumerate(drive.numbers):
        left_file = left_stream.files[index]
        left, right = _grey_pair(drive.folder, left_file, right_stream.files[index])
        first_shape = first_shape or left.shape
        if left.shape != first_shape:
            raise InputError(
                f"{left_file}: {left.shape[1]}×{left.shape[0]}, but the drive's first frame is "
                f"{first_shape[1]}×{first_shape[0]}"
            )
        stamps = StreamStamps(*(stream.stamps[index] for stream in drive.streams.values()))
        yield BagFrame(
            left,
            right,
            None,
            camera,
            (stamps.left - left_stream.stamps[0]) / 1e9,
            read_velodyne_bin(scans.files[index]),
            extrinsic,
            (cx, cy),
            stamps=stamps,
            odometry=poses[index],
            lidar_mount=mount,
            number=number,
        )


def methods_for(width: int, max_disparity: float) -> list[StereoMethod]:
    """The default methods with a disparity range that covers ``max_disparity``."""
    needed = 16 * math.ceil((max_disparity + 2) / 16)
    methods = default_methods(width)
    return [
        dataclasses.replace(m, num_disparities=needed) if m.num_disparities < needed else m
        for m in methods
    ]


def _disparity_reach(frame: BagFrame) -> float:
    """The largest disparity the methods must search: the GT's, else the scan's, else 64 px."""
    reference = frame.gt
    cloud, extrinsic, camera = frame.cloud, frame.cloud_to_camera, frame.camera
    if reference is None and cloud is not None and extrinsic is not None and camera is not None:
        height, width = frame.left.shape[:2]
        cx, cy = frame.principal or (width / 2.0 - 0.5, height / 2.0 - 0.5)
        intrinsic = np.array([[camera.f, 0, cx], [0, camera.f, cy], [0, 0, 1]])
        reference = project_cloud(
            cloud, intrinsic @ extrinsic[:3], (height, width), camera
        ).disparity
    finite = reference[np.isfinite(reference)] if reference is not None else np.empty(0)
    return float(finite.max()) if finite.size and finite.max() > 0 else 64.0


@dataclass(frozen=True)
class Estimates:
    """External predictions of one method (``--est NAME=DIR``): frame number → file."""

    name: str
    folder: Path
    files: dict[int, Path]

    def message_values(
        self, number: int, shape: tuple[int, int]
    ) -> tuple[np.ndarray, float, float]:
        """Frame ``number``'s map as DisparityImage values, ``min_disparity``, ``max_disparity``.

        Valid pixels are what the file's convention says (finite and > 0: 0 of a PNG, inf or
        NaN of a PFM are missing); the range is theirs and missing pixels are ``min − 1``, as
        stereo_image_proc marks them.
        """
        file = self.files.get(number)
        if file is None:
            numbers = sorted(self.files)
            raise InputError(
                f"--est {self.name}={self.folder}: no map for frame {number} (expected a file "
                f"named by the frame's number, e.g. {number:06d}.png); the folder has "
                f"{len(numbers)} maps, frames {numbers[0]}–{numbers[-1]}"
            )
        values = read_disparity(file)
        if values.shape != shape:
            raise ShapeMismatchError(
                f"{file}: --est {self.name} map is {values.shape[1]}×{values.shape[0]}, the "
                f"images are {shape[1]}×{shape[0]}"
            )
        valid = np.isfinite(values) & (values > 0)
        low, high = (
            (float(values[valid].min()), float(values[valid].max())) if valid.any() else (1.0, 1.0)
        )
        return np.where(valid, values, np.float32(low - 1.0)).astype(np.float32), low, high


def estimates_from(name: str, folder: Path, reserved: Iterable[str] = ()) -> Estimates:
    """Index ``--est NAME=DIR``: ``<digits>.png|pfm|npy`` files, the digits the frame number."""
    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", name):
        raise ConfigurationError(
            f"--est {name}={folder}: NAME must be a ROS topic name part (a letter, then "
            "letters, digits or _)"
        )
    if name in set(reserved):
        raise ConfigurationError(f"--est {name}={folder}: {name} is already a method's name")
    if not folder.is_dir():
        raise InputError(f"--est {name}={folder}: not a folder")
    files: dict[int, Path] = {}
    for entry in sorted(folder.iterdir()):
        match = _EST_FILE.match(entry.name)
        if match is None or not entry.is_file():
            continue
        number = int(match.group(1))
        if number in files:
            raise InputError(
                f"--est {name}={folder}: {files[number].name} and {entry.name} are both frame "
                f"{number}"
            )
        files[number] = entry
    if not files:
        raise InputError(
            f"--est {name}={folder}: no maps named by frame number (NNNNNN{'|'.join(EST_SUFFIXES)})"
        )
    return Estimates(name, folder, files)


def method_latency_ns(order: int) -> int:
    """How long after its images' stamp a method's DisparityImage is logged (ns).

    20 ms plus 15 ms per method before it in the bag (its pipeline's processing time): the
    delay ``dispeval bag`` measures for it.
    """
    return 20_000_000 + 15_000_000 * order


def write_bag(
    path: Path,
    frames: Iterable[BagFrame],
    *,
    storage: str = "rosbag2-mcap",
    methods: Sequence[StereoMethod] | None = None,
    fps: float = 10.0,
    compress: bool = False,
    progress: Callable[[int], None] | None = None,
    estimates: Sequence[Estimates] = (),
    delay: Callable[[int, int], int | None] | None = None,
    confidence: bool = False,
) -> dict[str, object]:
    """Write every frame (images, CameraInfo, GT, each method's disparity); returns a summary.

    ``estimates`` are published beside the methods, frame by frame (by
    :attr:`BagFrame.number`, else the frame's position). ``delay(order, index)``: how long
    after its stamp the ``order``-th source's map of frame ``index`` is logged (ns), None to
    leave it out (a frame that source missed); default :func:`method_latency_ns` of order.
    ``confidence``: each OpenCV method's left-right confidence too
    (:func:`~dispeval_ros.testbed.methods.left_right_confidence`, on :func:`confidence_topic`,
    logged with its disparity).
    """
    written = 0
    clouds = 0
    poses = 0
    mounted = False  # /tf_static written
    cloud_offset = 0
    has_gt = False
    gt_source = ""
    chosen: list[StereoMethod] | None = list(methods) if methods else None
    with BagWriter(path, storage, compress=compress) as bag:
        typestore = bag.typestore
        for topic, msgtype in (
            (LEFT_IMAGE, "sensor_msgs/msg/Image"),
            (RIGHT_IMAGE, "sensor_msgs/msg/Image"),
            (LEFT_INFO, "sensor_msgs/msg/CameraInfo"),
            (RIGHT_INFO, "sensor_msgs/msg/CameraInfo"),
        ):
            bag.add_topic(topic, msgtype)
        registered = False
        for index, frame in enumerate(frames):
            height, width = frame.left.shape[:2]
            if chosen is None:
                chosen = methods_for(width, _disparity_reach(frame))
            if not registered:
                has_gt, gt_source = frame.gt is not None, frame.gt_source
                if has_gt:
                    bag.add_topic(GT_TOPIC, "sensor_msgs/msg/Image")
                for name in _names(chosen, estimates):
                    bag.add_topic(disparity_topic(name), "stereo_msgs/msg/DisparityImage")
                for method in chosen if confidence else ():
                    bag.add_topic(confidence_topic(method.name), "sensor_msgs/msg/Image")
                registered = True
            synthetic = START_NS + round(frame.stamp * 1e9)
            stamps = frame.stamps or StreamStamps(synthetic, synthetic, synthetic, synthetic)
            stamp = stamps.left
            camera = frame.camera
            mount_edges = None if mounted else _mount_edges(frame, stamps)
            if mount_edges is not None:  # latched once, as a static_transform_publisher does
                edges, first = mount_edges
                bag.add_topic(TF_STATIC_TOPIC, "tf2_msgs/msg/TFMessage")
                bag.write(TF_STATIC_TOPIC, first, tf_static_to_msg(typestore, edges, first))
                mounted = True
            if frame.cloud is not None and frame.cloud_to_camera is not None:
                if clouds == 0:
                    bag.add_topic(CLOUD_TOPIC, "sensor_msgs/msg/PointCloud2")
                cloud = cloud_to_msg(typestore, frame.cloud, stamps.cloud, LIDAR_FRAME)
                bag.write(CLOUD_TOPIC, stamps.cloud + 2_000_000, cloud)
                cloud_offset = max(cloud_offset, abs(stamps.cloud - stamp))
                clouds += 1
            if frame.odometry is not None:
                odometry = StaticTransform(ODOM_FRAME, BASE_FRAME, frame.odometry)
                message = tf_static_to_msg(typestore, [odometry], stamps.odometry)
                bag.write(TF_TOPIC, stamps.odometry, message)
                poses += 1
            bag.write(
                LEFT_IMAGE,
                stamp,
                image_to_msg(typestore, frame.left, stamp, "stereo_left", "mono8"),
            )
            bag.write(
                RIGHT_IMAGE,
                stamps.right,
                image_to_msg(typestore, frame.right, stamps.right, "stereo_right", "mono8"),
            )
            if camera is not None:
                cx, cy = frame.principal or (None, None)
                for topic, right, info_stamp in (
                    (LEFT_INFO, False, stamp),
                    (RIGHT_INFO, True, stamps.right),
                ):
                    info = camera_info_to_msg(
                        typestore, camera, width, height, info_stamp, "stereo_left", right, cx, cy
                    )
                    bag.write(topic, info_stamp, info)
            if frame.gt is not None:
                bag.write(
                    GT_TOPIC,
                    stamp + 1_000_000,
                    image_to_msg(typestore, frame.gt, stamp, "stereo_left", "32FC1"),
                )
            outputs: list[tuple[str, np.ndarray, float, float]] = [
                (m.name, m.compute(frame.left, frame.right), m.min_disparity, m.max_disparity)
                for m in chosen
            ]
            number = index if frame.number is None else frame.number
            for source in estimates:
                outputs.append((source.name, *source.message_values(number, (height, width))))
            for order, (name, disparity, low, high) in enumerate(outputs):
                late = method_latency_ns(order) if delay is None else delay(order, index)
                if late is None:
                    continue
                message = disparity_to_msg(
                    typestore,
                    disparity,
                    stamp,
                    "stereo_left",
                    camera.f if camera else 0.0,
                    camera.baseline if camera else 0.0,
                    low,
                    high,
                    doffs=camera.doffs if camera else 0.0,
                )
                bag.write(disparity_topic(name), stamp + late, message)
                if confidence and order < len(chosen):
                    rating = left_right_confidence(chosen[order], frame.left, frame.right,
                                                   disparity)  # fmt: skip
                    image = image_to_msg(typestore, rating, stamp, "stereo_left", "mono8")
                    bag.write(confidence_topic(name), stamp + late, image)
            written += 1
            if progress is not None:
                progress(written)
    if written == 0:
        raise InputError(f"{path}: no frame to write")
    return {
        "path": str(path),
        "storage": storage,
        "frames": written,
        "fps": fps,
        "methods": {name: disparity_topic(name) for name in _names(chosen, estimates)},
        **(
            {
                "latency_ms": {
                    name: method_latency_ns(order) / 1e6
                    for order, name in enumerate(_names(chosen, estimates))
                }
            }
            if delay is None
            else {}
        ),
        "estimates": {e.name: str(e.folder) for e in estimates},
        **(
            {
                "confidences": {m.name: confidence_topic(m.name) for m in chosen or ()},
                "confidence_preset": CONFIDENCE_PRESET,
            }
            if confidence
            else {}
        ),
        "gt": GT_TOPIC if has_gt else None,
        **({"gt_source": gt_source} if gt_source else {}),
        "camera_info": [LEFT_INFO, RIGHT_INFO],
        **(
            {
                "gt_cloud": CLOUD_TOPIC,
                "tf_static": TF_STATIC_TOPIC,
                "cloud_offset_ms": cloud_offset / 1e6,
            }
            if clouds
            else {"tf_static": TF_STATIC_TOPIC}
            if mounted
            else {}
        ),
        **({"tf": TF_TOPIC} if poses else {}),
    }


def _names(methods: Sequence[StereoMethod] | None, estimates: Sequence[Estimates]) -> list[str]:
    """Every DisparityImage source of a bag: the methods, then the external estimates."""
    return [m.name for m in methods or []] + [e.name for e in estimates]


def synthetic_frames(
    n_frames: int,
    width: int,
    height: int,
    fps: float,
    seed: int,
    lidar: LidarModel | None = None,
    *,
    odometry: bool = True,
) -> Iterator[BagFrame]:
    """The synthetic driving sequence of the test-bed, with a LiDAR's scans if ``lidar``.

    With ``odometry`` each frame carries the drive's exact motion as odom → base_link (odom:
    base_link at the first frame), base_link being where the LiDAR's mount puts it whether or
    not the scans are simulated, so ego-motion can be scored from the bag's /tf.
    """
    world, rig = driving_setup(width, height, fps, seed)
    mount = LIDAR_MOUNT @ invert_rigid(lidar_to_camera(rig, lidar))  # base_link → camera
    for index, frame in enumerate(make_driving_sequence(n_frames, width, height, fps, seed)):
        bag_frame = dataclasses.replace(from_stereo_frame(frame), principal=(rig.cx, rig.cy))
        if odometry:
            motion = rig_motion(rig, rig.at(frame.stamp))
            bag_frame = dataclasses.replace(
                bag_frame, odometry=mount @ motion @ invert_rigid(mount), camera_mount=mount
            )
        if lidar is not None:
            world_t, rig_t = driving_world_at(world, rig, index / fps)
            bag_frame = dataclasses.replace(
                bag_frame,
                cloud=simulate_scan(world_t, rig_t, lidar),
                cloud_to_camera=lidar_to_camera(rig_t, lidar),
            )
        yield bag_frame


def from_stereo_frame(frame: StereoFrame) -> BagFrame:
    """A test-bed frame as a bag frame (the right-view GT is not recorded)."""
    return BagFrame(frame.left, frame.right, frame.gt_left, frame.camera, frame.stamp)
