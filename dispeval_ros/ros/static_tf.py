"""Static transforms for the rclpy evaluator: tf2_ros where installed, else raw /tf_static.

Only glue: tf2_ros's buffer answers the core's extrinsic lookups, or (without tf2_ros) the
node subscribes to ``/tf_static`` with ``tf2_msgs`` and the core composes the chain itself.
Without either, point-cloud ground truth needs the ``lidar_extrinsic`` parameter.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from dispeval_ros.core.transforms import matrix_from_pose
from dispeval_ros.errors import CalibrationError, ConfigurationError

STATIC_TF_DEPTH = 100


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


def tf_message_class() -> Any:
    """``tf2_msgs.msg.TFMessage``, or a one-line error saying what to do without it."""
    try:
        from tf2_msgs.msg import TFMessage
    except ImportError:
        raise ConfigurationError(
            "gt_kind pointcloud without lidar_extrinsic reads /tf_static, but neither tf2_ros "
            "nor tf2_msgs can be imported: install them or set the parameter lidar_extrinsic"
        ) from None
    return TFMessage
