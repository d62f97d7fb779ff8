"""Transforms for the rclpy evaluator: tf2_ros where installed, else raw /tf_static.

Only glue: tf2_ros's buffer answers the core's extrinsic lookups, or (without tf2_ros) the
node subscribes to ``/tf_static`` with ``tf2_msgs`` and the core composes the chain itself.
Without either, point-cloud ground truth needs the ``lidar_extrinsic`` parameter. With
``egomotion`` the node hands ``/tf``, ``/tf_static`` (``tf2_msgs``) and ``nav_msgs/Odometry``
to the core's motion source, subscribed with tf2_ros's QoS.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from dispeval_ros.core.transforms import matrix_from_pose
from dispeval_ros.errors import CalibrationError, ConfigurationError

STATIC_TF_DEPTH = 100
DYNAMIC_TF_DEPTH = 100
"""tf2_ros's ``DynamicListenerQoS``: keep last 100, reliable, volatile (ros2/geometry2
tf2_ros/qos.hpp); its ``StaticListenerQoS`` is :func:`static_tf_qos`'s, transient local."""


def dynamic_tf_qos(reliable: bool = True) -> Any:
    """``/tf``'s QoS as tf2_ros's listener has it; ``reliable`` False also matches best effort.

    An odometry topic is subscribed best effort (both kinds of publisher match it).
    """
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=DYNAMIC_TF_DEPTH,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.VOLATILE,
    )


def static_tf_qos() -> Any:
    """``/tf_static``'s QoS (tf2_ros's static listener): reliable, transient local."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=STATIC_TF_DEPTH,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )


def tf2_lookup(node: Any) -> tuple[Callable[[str, str], np.ndarray], Any] | None:
    """A ``(camera frame, cloud frame) → 4×4`` lookup through tf2_ros (None: not installed).

    Returns the lookup and the listener (keep it alive as long as the node).
    """
    try:
        import tf2_ros
        from rclpy.time import Time
    except ImportError:
        return None
    buffer = tf2_ros.Buffer()
    listener = tf2_ros.StaticTransformListener(buffer, node)

    def lookup(target: str, source: str) -> np.ndarray:
        try:
            stamped = buffer.lookup_transform(target, source, Time())
        except tf2_ros.TransformException as error:
            frames = buffer.all_frames_as_string().strip().replace("\n", "; ")
            raise CalibrationError(
                f"no static transform from the cloud frame '{source}' to the camera frame "
                f"'{target}' ({error}); frames known to tf2: {frames or 'none'}"
            ) from None
        translation, rotation = stamped.transform.translation, stamped.transform.rotation
        return matrix_from_pose(
            [translation.x, translation.y, translation.z],
            [rotation.x, rotation.y, rotation.z, rotation.w],
        )

    return lookup, listener


def tf_message_class(required: bool = True, egomotion: bool = False) -> Any:
    """``tf2_msgs.msg.TFMessage``, else a one-line error saying what to do.

    Not ``required`` (egomotion with an odometry topic): None without tf2_msgs.
    """
    try:
        from tf2_msgs.msg import TFMessage
    except ImportError:
        if not required:
            return None
        if egomotion:
            raise ConfigurationError(
                "egomotion reads the camera's motion from /tf, but tf2_msgs cannot be "
                "imported: install it or set the parameter odometry_topic (nav_msgs/Odometry)"
            ) from None
        raise ConfigurationError(
            "gt_kind pointcloud without lidar_extrinsic reads /tf_static, but neither tf2_ros "
            "nor tf2_msgs can be imported: install them or set the parameter lidar_extrinsic"
        ) from None
    return TFMessage


def odometry_class() -> Any:
    """``nav_msgs.msg.Odometry``, or a one-line error naming the parameter."""
    try:
        from nav_msgs.msg import Odometry
    except ImportError:
        raise ConfigurationError(
            "parameter odometry_topic reads nav_msgs/msg/Odometry, but nav_msgs cannot be "
            "imported: install it (ros-$ROS_DISTRO-nav-msgs)"
        ) from None
    return Odometry


def mount_matrix(values: tuple[float, ...] | None) -> np.ndarray | None:
    """The ``camera_mount`` parameter's 16 numbers as a 4×4 (None: none given)."""
    return None if values is None else np.asarray(values, dtype=np.float64).reshape(4, 4)
