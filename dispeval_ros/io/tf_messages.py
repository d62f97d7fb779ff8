"""``/tf`` messages as stamped edges for :class:`~dispeval_ros.core.TransformHistory`.

``tf2_msgs/TFMessage`` and ``nav_msgs/Odometry`` as rosbags reads them from ROS 2 and ROS 1
bags and as rclpy delivers them: they share attribute names, so no ROS import is needed.
"""

from __future__ import annotations

from typing import Any

from dispeval_ros.core.transform_history import TransformHistory
from dispeval_ros.core.transforms import StaticTransform, matrix_from_pose
from dispeval_ros.errors import CalibrationError, DispevalError, InputError
from dispeval_ros.io.messages import stamp_ns, static_transforms_from_msg

__all__ = ["add_tf_message", "odometry_from_msg", "transforms_from_msg"]


def _stamp(header: Any, where: str) -> int:
    try:
        return stamp_ns(header)
    except InputError as error:
        raise InputError(f"{where}: {error}") from None


def transforms_from_msg(msg: Any, topic: str = "") -> list[tuple[int, StaticTransform]]:
    """Each transform of a ``TFMessage`` (``/tf``) with its own header stamp (ns)."""
    where = f"TFMessage on {topic}" if topic else "TFMessage message"
    edges = static_transforms_from_msg(msg, topic)
    return [
        (_stamp(stamped.header, where), edge)
        for stamped, edge in zip(msg.transforms, edges, strict=True)
    ]


def odometry_from_msg(msg: Any, topic: str = "") -> tuple[int, StaticTransform]:
    """A ``nav_msgs/Odometry`` as the edge ``header.frame_id → child_frame_id`` at its stamp."""
    where = f"Odometry on {topic}" if topic else "Odometry message"
    try:
        header, pose = msg.header, msg.pose.pose
        position, orientation = pose.position, pose.orientation
        matrix = matrix_from_pose(
            [float(position.x), float(position.y), float(position.z)],
            [
                float(orientation.x),
                float(orientation.y),
                float(orientation.z),
                float(orientation.w),
            ],
        )
        parent, child = str(header.frame_id), str(msg.child_frame_id)
    except (AttributeError, TypeError, ValueError):
        raise InputError(
            f"{where}: an Odometry needs header, child_frame_id and pose.pose with position "
            "x, y, z and orientation x, y, z, w"
        ) from None
    except CalibrationError as error:
        raise CalibrationError(f"{where}: {error}") from None
    return _stamp(header, where), StaticTransform(parent, child, matrix)


def add_tf_message(
    history: TransformHistory, msg: Any, topic: str, *, static: bool = False
) -> list[str]:
    """Add a TFMessage to ``history`` (``static``: from /tf_static); its problems, one line each.

    What can be kept is kept: a message that cannot be decoded is one problem, a transform the
    history refuses (two parents, too old, ...) another, and the others of the message stay.
    """
    try:
        if static:
            history.add_static(static_transforms_from_msg(msg, topic))
            return []
        return history.extend(transforms_from_msg(msg, topic))
    except DispevalError as error:
        return [str(error)]
