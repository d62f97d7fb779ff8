"""I/O adapters around the core: files, dataset folders, ROS messages, bags, results database."""

from typing import TYPE_CHECKING

from dispeval_ros.lazy import lazy_exports

# the adapters (OpenCV, rosbags, SQLite) load when a name is first used
__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "dispeval_ros.io.bags": (
            "BagSource",
            "BagWriter",
            "TopicInfo",
            "require_topic",
        ),
        "dispeval_ros.io.calib": ("read_calib",),
        "dispeval_ros.io.files": (
            "read_disparity",
            "read_mask",
            "read_pfm",
            "read_stereo_pair",
            "write_disparity_png16",
            "write_pfm",
        ),
        "dispeval_ros.io.lidar": (
            "LidarCalibration",
            "read_extrinsic",
            "read_lidar_calib",
            "read_velodyne_bin",
        ),
        "dispeval_ros.io.messages": (
            "CloudFrame",
            "DisparityFrame",
            "ImageFrame",
            "camera_from_infos",
            "cloud_from_msg",
            "disparity_from_msg",
            "gt_disparity",
            "image_from_msg",
            "stamp_ns",
        ),
        "dispeval_ros.io.scenes": (
            "Scene",
            "list_frames",
            "load_scene",
            "scene_folders",
        ),
        "dispeval_ros.io.store": (
            "FrameScores",
            "MatchCounts",
            "Problem",
            "ResultsStore",
        ),
        "dispeval_ros.io.tables": (
            "read_objectives_csv",
            "write_objectives_csv",
        ),
        "dispeval_ros.io.tf_messages": (
            "add_tf_message",
            "odometry_from_msg",
            "transforms_from_msg",
        ),
    },
)

if TYPE_CHECKING:
    from dispeval_ros.io.bags import BagSource, BagWriter, TopicInfo, require_topic
    from dispeval_ros.io.calib import read_calib
    from dispeval_ros.io.files import (
        read_disparity,
        read_mask,
        read_pfm,
        read_stereo_pair,
        write_disparity_png16,
        write_pfm,
    )
    from dispeval_ros.io.lidar import (
        LidarCalibration,
        read_extrinsic,
        read_lidar_calib,
        read_velodyne_bin,
    )
    from dispeval_ros.io.messages import (
        CloudFrame,
        DisparityFrame,
        ImageFrame,
        camera_from_infos,
        cloud_from_msg,
        disparity_from_msg,
        gt_disparity,
        image_from_msg,
        stamp_ns,
    )
    from dispeval_ros.io.scenes import Scene, list_frames, load_scene, scene_folders
    from dispeval_ros.io.store import FrameScores, MatchCounts, Problem, ResultsStore
    from dispeval_ros.io.tables import read_objectives_csv, write_objectives_csv
    from dispeval_ros.io.tf_messages import add_tf_message, odometry_from_msg, transforms_from_msg

__all__ = [
    "BagSource",
    "BagWriter",
    "CloudFrame",
    "DisparityFrame",
    "FrameScores",
    "ImageFrame",
    "LidarCalibration",
    "MatchCounts",
    "Problem",
    "ResultsStore",
    "Scene",
    "TopicInfo",
    "add_tf_message",
    "camera_from_infos",
    "cloud_from_msg",
    "disparity_from_msg",
    "gt_disparity",
    "image_from_msg",
    "list_frames",
    "load_scene",
    "odometry_from_msg",
    "read_calib",
    "read_disparity",
    "read_extrinsic",
    "read_lidar_calib",
    "read_mask",
    "read_objectives_csv",
    "read_pfm",
    "read_stereo_pair",
    "read_velodyne_bin",
    "require_topic",
    "scene_folders",
    "stamp_ns",
    "transforms_from_msg",
    "write_disparity_png16",
    "write_objectives_csv",
    "write_pfm",
]
