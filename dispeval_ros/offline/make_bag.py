"""Write test-bed bags: rectified stereo, CameraInfo, exact GT and real stereo methods' output.

Every method's output is published as a ``stereo_msgs/DisparityImage`` exactly as ROS 2
stereo_image_proc does (32FC1, ``f``, ``t``, ``min/max_disparity``, ``delta_d = 1/16``,
invalid pixels = ``min_disparity − 1``, values and range offset-corrected by the camera's
``doffs`` as the message defines, the images' header); the ground truth is an Image of the
dataset's own ``x_l − x_r`` (the CameraInfo pair carries ``doffs``). Methods are logged a
little after the images as a real pipeline would (each method has its own processing latency),
so the bag exercises the stamp join the same way a recording of a robot does.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from dispeval_ros.core import Camera
from dispeval_ros.core.transforms import StaticTransform, invert_rigid, matrix_from_pose
from dispeval_ros.errors import InputError
from dispeval_ros.io.bags import BagWriter
from dispeval_ros.io.messages import (
    camera_info_to_msg,
    cloud_to_msg,
    disparity_to_msg,
    image_to_msg,
    tf_static_to_msg,
)
from dispeval_ros.io.scenes import list_frames
from dispeval_ros.stream.core import CoreConfig
from dispeval_ros.testbed import StereoFrame, StereoMethod, default_methods, make_driving_sequence
from dispeval_ros.testbed.lidar import LidarModel, lidar_to_camera, simulate_scan
from dispeval_ros.testbed.scene import driving_setup, driving_world_at

LEFT_IMAGE = "/stereo/left/image_rect"
RIGHT_IMAGE = "/stereo/right/image_rect"
LEFT_INFO = "/stereo/left/camera_info"
RIGHT_INFO = "/stereo/right/camera_info"
GT_TOPIC = "/stereo/ground_truth/disparity"
CLOUD_TOPIC = "/lidar/points"
TF_STATIC_TOPIC = "/tf_static"
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


@dataclass(frozen=True)
class BagFrame:
    """What one frame of a test-bed bag holds; ``camera`` is None for uncalibrated scenes."""

    left: np.ndarray
    right: np.ndarray
    gt: np.ndarray
    camera: Camera | None
    stamp: float
    cloud: np.ndarray | None = None
    """A LiDAR scan (N×3, the LiDAR's frame) taken at ``stamp``, or None."""
    cloud_to_camera: np.ndarray | None = None
    """The LiDAR → left optical frame transform (4×4) of ``cloud``."""
    principal: tuple[float, float] | None = None
    """The left camera's ``(cx, cy)`` in px (default: the image centre)."""


def static_transforms(cloud_to_camera: np.ndarray) -> list[StaticTransform]:
    """/tf_static of a vehicle: base_link → LiDAR and base_link → left optical frame."""
    camera_pose = LIDAR_MOUNT @ invert_rigid(cloud_to_camera)
    return [
        StaticTransform(BASE_FRAME, LIDAR_FRAME, LIDAR_MOUNT),
        StaticTransform(BASE_FRAME, CAMERA_FRAME, camera_pose),
    ]


def bag_config(methods: Sequence[str]) -> CoreConfig:
    """What ``dispeval bag`` needs to read these methods from a bag :func:`write_bag` wrote."""
    return CoreConfig(
        methods={name: disparity_topic(name) for name in methods},
        gt_topic=GT_TOPIC,
        left_info_topic=LEFT_INFO,
        right_info_topic=RIGHT_INFO,
    )


def dataset_frames(folder: Path) -> Iterator[BagFrame]:
    """Frames of a dataset scene folder (any layout ``load_scene`` reads) with its images."""
    for index, scene in enumerate(list_frames(folder)):
        if scene.left is None or scene.right is None:
            raise InputError(
                f"{folder}: the scene has no left/right images to run stereo methods on"
            )
        left = cv2.imread(str(scene.left), cv2.IMREAD_GRAYSCALE)
        right = cv2.imread(str(scene.right), cv2.IMREAD_GRAYSCALE)
        if left is None or right is None:
            raise InputError(
                f"{folder}: cannot read the images {scene.left.name}, {scene.right.name}"
            )
        if left.shape != scene.gt.shape or right.shape != scene.gt.shape:
            raise InputError(
                f"{folder}: images are {left.shape} and {right.shape} but the GT is {scene.gt.shape}"
            )
        cloud = extrinsic = principal = None
        if scene.lidar is not None and scene.lidar_calib is not None:
            from dispeval_ros.io.lidar import read_lidar_calib, read_velodyne_bin

            cloud = read_velodyne_bin(scene.lidar)
            extrinsic, cx, cy = read_lidar_calib(scene.lidar_calib).ros_view()
            principal = (cx, cy)
        yield BagFrame(
            left,
            right,
            scene.gt.astype(np.float32),
            scene.camera,
            float(index),
            cloud,
            extrinsic,
            principal,
        )


def methods_for(width: int, max_disparity: float) -> list[StereoMethod]:
    """The default methods with a disparity range that covers ``max_disparity``."""
    needed = 16 * math.ceil((max_disparity + 2) / 16)
    methods = default_methods(width)
    return [
        dataclasses.replace(m, num_disparities=needed) if m.num_disparities < needed else m
        for m in methods
    ]


def write_bag(
    path: Path,
    frames: Iterable[BagFrame],
    *,
    storage: str = "rosbag2-mcap",
    methods: Sequence[StereoMethod] | None = None,
    fps: float = 10.0,
    compress: bool = False,
    progress: Callable[[int], None] | None = None,
) -> dict[str, object]:
    """Write every frame (images, CameraInfo, GT, each method's disparity); returns a summary."""
    written = 0
    clouds = 0
    chosen: list[StereoMethod] | None = list(methods) if methods else None
    with BagWriter(path, storage, compress=compress) as bag:
        typestore = bag.typestore
        for topic, msgtype in (
            (LEFT_IMAGE, "sensor_msgs/msg/Image"),
            (RIGHT_IMAGE, "sensor_msgs/msg/Image"),
            (LEFT_INFO, "sensor_msgs/msg/CameraInfo"),
            (RIGHT_INFO, "sensor_msgs/msg/CameraInfo"),
            (GT_TOPIC, "sensor_msgs/msg/Image"),
        ):
            bag.add_topic(topic, msgtype)
        registered = False
        for frame in frames:
            height, width = frame.gt.shape
            if chosen is None:
                finite = frame.gt[np.isfinite(frame.gt)]
                chosen = methods_for(width, float(finite.max()) if finite.size else 64.0)
            if not registered:
                for method in chosen:
                    bag.add_topic(disparity_topic(method.name), "stereo_msgs/msg/DisparityImage")
                registered = True
            stamp = START_NS + round(frame.stamp * 1e9)
            camera = frame.camera
            if frame.cloud is not None and frame.cloud_to_camera is not None:
                if clouds == 0:  # latched once, as a robot's static_transform_publisher does
                    bag.add_topic(TF_STATIC_TOPIC, "tf2_msgs/msg/TFMessage")
                    bag.add_topic(CLOUD_TOPIC, "sensor_msgs/msg/PointCloud2")
                    edges = static_transforms(frame.cloud_to_camera)
                    bag.write(TF_STATIC_TOPIC, stamp, tf_static_to_msg(typestore, edges, stamp))
                cloud = cloud_to_msg(typestore, frame.cloud, stamp, LIDAR_FRAME)
                bag.write(CLOUD_TOPIC, stamp + 2_000_000, cloud)
                clouds += 1
            bag.write(
                LEFT_IMAGE,
                stamp,
                image_to_msg(typestore, frame.left, stamp, "stereo_left", "mono8"),
            )
            bag.write(
                RIGHT_IMAGE,
                stamp,
                image_to_msg(typestore, frame.right, stamp, "stereo_right", "mono8"),
            )
            if camera is not None:
                cx, cy = frame.principal or (None, None)
                for topic, right in ((LEFT_INFO, False), (RIGHT_INFO, True)):
                    info = camera_info_to_msg(
                        typestore, camera, width, height, stamp, "stereo_left", right, cx, cy
                    )
                    bag.write(topic, stamp, info)
            bag.write(
                GT_TOPIC,
                stamp + 1_000_000,
                image_to_msg(typestore, frame.gt, stamp, "stereo_left", "32FC1"),
            )
            for index, method in enumerate(chosen):
                disparity = method.compute(frame.left, frame.right)
                message = disparity_to_msg(
                    typestore,
                    disparity,
                    stamp,
                    "stereo_left",
                    camera.f if camera else 0.0,
                    camera.baseline if camera else 0.0,
                    method.min_disparity,
                    method.max_disparity,
                    doffs=camera.doffs if camera else 0.0,
                )
                latency = 20_000_000 + 15_000_000 * index  # a pipeline's processing time
                bag.write(disparity_topic(method.name), stamp + latency, message)
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
        "methods": {m.name: disparity_topic(m.name) for m in chosen or []},
        "gt": GT_TOPIC,
        "camera_info": [LEFT_INFO, RIGHT_INFO],
        **({"gt_cloud": CLOUD_TOPIC, "tf_static": TF_STATIC_TOPIC} if clouds else {}),
    }


def synthetic_frames(
    n_frames: int,
    width: int,
    height: int,
    fps: float,
    seed: int,
    lidar: LidarModel | None = None,
) -> Iterator[BagFrame]:
    """The synthetic driving sequence of the test-bed, with a LiDAR's scans if ``lidar``."""
    world, rig = driving_setup(width, height, fps, seed)
    for index, frame in enumerate(make_driving_sequence(n_frames, width, height, fps, seed)):
        bag_frame = dataclasses.replace(from_stereo_frame(frame), principal=(rig.cx, rig.cy))
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
