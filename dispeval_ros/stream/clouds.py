"""A LiDAR point cloud as one frame's sparse ground truth: projected into the left camera.

Moved out of :mod:`~dispeval_ros.stream.core` (which calls it for point-cloud GT) to keep it
short.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from dispeval_ros.core import Camera
from dispeval_ros.core.projection import (
    CloudFilter,
    CloudProjection,
    project_cloud,
    rectified_projection,
)
from dispeval_ros.errors import CalibrationError, InputError
from dispeval_ros.io.messages import cloud_from_msg, rectified_camera_from_info


def cloud_disparity(
    msg: Any,
    topic: str,
    left: str | None,
    camera: Camera | None,
    shape: tuple[int, ...],
    infos: Mapping[str, Any],
    extrinsic: Callable[[str, str], np.ndarray],
    cloud_filter: CloudFilter,
) -> CloudProjection:
    """Project the PointCloud2 ``msg`` of ``topic`` into the left camera (CameraInfo ``left``).

    ``infos``: the CameraInfo messages by topic; ``extrinsic(camera frame, cloud frame)``: the
    cloud → camera transform. Every problem is one line naming the topic: no x/y/z, no camera,
    no chain of static transforms, a CameraInfo of another size than the disparity, or no
    point in view.
    """
    cloud = cloud_from_msg(msg, topic)
    if camera is None or left is None or left not in infos:
        raise CalibrationError(
            f"no camera yet for the cloud on {topic}: waiting for the CameraInfo topics"
        )
    view = rectified_camera_from_info(infos[left], left)
    size = (view.height, view.width) if view.height > 0 and view.width > 0 else shape[:2]
    if tuple(size) != tuple(shape[:2]):
        raise InputError(
            f"CameraInfo on {left} is {view.width}×{view.height} but the disparity is "
            f"{shape[1]}×{shape[0]}: the cloud cannot be projected into that image"
        )
    matrix = rectified_projection(
        extrinsic(view.frame_id, cloud.frame_id), view.rectification, view.projection
    )
    projected = project_cloud(
        cloud.points, matrix, (int(size[0]), int(size[1])), camera, cloud_filter
    )
    if projected.points and not projected.in_front:
        raise CalibrationError(
            f"the cloud on {topic}: all {projected.points} points are behind the camera "
            f"'{view.frame_id}' (Z ≤ 0) with this extrinsic; is it inverted (camera → LiDAR)?"
        )
    if not projected.kept:
        raise InputError(
            f"the cloud on {topic}: none of its {projected.points} points lands in the "
            f"{size[1]}×{size[0]} image ({projected.in_front} in front of the camera)"
        )
    return projected
