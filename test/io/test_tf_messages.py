"""/tf messages (TFMessage, Odometry) as stamped edges: ROS 2 and ROS 1 types, rospy style."""

from __future__ import annotations

import math
from types import SimpleNamespace as NS
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from dispeval_ros.core.transform_history import TransformHistory
from dispeval_ros.errors import CalibrationError, InputError
from dispeval_ros.io.tf_messages import add_tf_message, odometry_from_msg, transforms_from_msg

HALF = math.sqrt(0.5)


def _typestore(store: Stores) -> Any:
    typestore = get_typestore(store)
    if "tf2_msgs/msg/TFMessage" not in typestore.types:  # rosbags' ROS 1 store lacks it
        typestore.register(
            get_types_from_msg(
                "geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"
            )
        )
    return typestore


def _header(types: Any, stamp_ns: int, frame: str) -> Any:
    time = types["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    header = types["std_msgs/msg/Header"]
    if "seq" in header.__dataclass_fields__:
        return header(seq=0, stamp=time, frame_id=frame)
    return header(stamp=time, frame_id=frame)


def _tf(typestore: Any, edges: list[tuple[int, str, str, float, float]]) -> Any:
    """A TFMessage of ``(stamp, parent, child, x, yaw)`` edges: each its own stamp."""
    types = typestore.types
    stamped = []
    for stamp, parent, child, x, yaw in edges:
        transform = types["geometry_msgs/msg/Transform"](
            translation=types["geometry_msgs/msg/Vector3"](x=x, y=0.0, z=0.0),
            rotation=types["geometry_msgs/msg/Quaternion"](
                x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
            ),
        )
        stamped.append(
            types["geometry_msgs/msg/TransformStamped"](
                header=_header(types, stamp, parent), child_frame_id=child, transform=transform
            )
        )
    return types["tf2_msgs/msg/TFMessage"](transforms=stamped)


@pytest.mark.parametrize("store", [Stores.ROS2_HUMBLE, Stores.ROS1_NOETIC])
def test_tf_message_edges_keep_their_own_stamps(store: Stores) -> None:
    typestore = _typestore(store)
    msg = _tf(
        typestore,
        [
            (1_500_000_001, "odom", "base_link", 2.0, math.pi / 2),
            (1_600_000_002, "/base_link", "arm", 0.5, 0.0),
        ],
    )
    (first, second) = transforms_from_msg(msg, "/tf")
    assert first[0] == 1_500_000_001
    assert (first[1].parent, first[1].child) == ("odom", "base_link")
    np.testing.assert_allclose(
        first[1].matrix,
        [[0, -1, 0, 2.0], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
        atol=1e-15,
    )
    assert second[0] == 1_600_000_002
    # Into the history: a leading slash names the same frame.
    history = TransformHistory()
    assert history.extend(transforms_from_msg(msg, "/tf")) == []
    assert [(s.parent, s.child) for s in history.spans()] == [
        ("base_link", "arm"),
        ("odom", "base_link"),
    ]


def test_rospy_style_stamps_and_odometry() -> None:
    quaternion = NS(x=0.0, y=0.0, z=HALF, w=HALF)
    odometry = NS(
        header=NS(stamp=NS(secs=3, nsecs=250), frame_id="odom"),
        child_frame_id="base_link",
        pose=NS(pose=NS(position=NS(x=1.0, y=2.0, z=3.0), orientation=quaternion), covariance=[]),
    )
    stamp, edge = odometry_from_msg(odometry, "/odom")
    assert stamp == 3_000_000_250
    assert (edge.parent, edge.child) == ("odom", "base_link")
    np.testing.assert_allclose(
        edge.matrix, [[0, -1, 0, 1.0], [1, 0, 0, 2.0], [0, 0, 1, 3.0], [0, 0, 0, 1]], atol=1e-15
    )
    typestore = _typestore(Stores.ROS2_HUMBLE)
    types = typestore.types
    ros2 = types["nav_msgs/msg/Odometry"](
        header=_header(types, 7_000_000_001, "odom"),
        child_frame_id="base_link",
        pose=types["geometry_msgs/msg/PoseWithCovariance"](
            pose=types["geometry_msgs/msg/Pose"](
                position=types["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=3.0),
                orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=HALF, w=HALF),
            ),
            covariance=np.zeros(36),
        ),
        twist=types["geometry_msgs/msg/TwistWithCovariance"](
            twist=types["geometry_msgs/msg/Twist"](
                linear=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                angular=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
            ),
            covariance=np.zeros(36),
        ),
    )
    stamp, edge2 = odometry_from_msg(ros2)
    assert stamp == 7_000_000_001
    np.testing.assert_allclose(edge2.matrix, edge.matrix, atol=0)


def test_bad_messages_are_one_line() -> None:
    with pytest.raises(InputError, match=r"^Odometry on /odom: an Odometry needs header"):
        odometry_from_msg(NS(header=NS(frame_id="odom")), "/odom")
    zero = NS(x=0.0, y=0.0, z=0.0, w=0.0)
    broken = NS(
        header=NS(stamp=NS(sec=1, nanosec=0), frame_id="odom"),
        child_frame_id="base_link",
        pose=NS(pose=NS(position=NS(x=0.0, y=0.0, z=0.0), orientation=zero)),
    )
    with pytest.raises(CalibrationError, match=r"^Odometry on /odom: a pose needs .* non-zero"):
        odometry_from_msg(broken, "/odom")
    no_stamp = NS(
        transforms=[
            NS(
                header=NS(frame_id="odom"),
                child_frame_id="base_link",
                transform=NS(
                    translation=NS(x=0.0, y=0.0, z=0.0), rotation=NS(x=0.0, y=0.0, z=0.0, w=1.0)
                ),
            )
        ]
    )
    with pytest.raises(InputError, match=r"^TFMessage on /tf: expected a std_msgs/Header"):
        transforms_from_msg(no_stamp, "/tf")


def test_add_tf_message_keeps_what_it_can() -> None:
    typestore = _typestore(Stores.ROS2_HUMBLE)
    history = TransformHistory()
    mount = _tf(typestore, [(0, "base_link", "camera", 0.5, 0.0)])
    assert add_tf_message(history, mount, "/tf_static", static=True) == []
    mixed = _tf(
        typestore,
        [(10, "odom", "base_link", 1.0, 0.0), (10, "map", "camera", 0.0, 0.0)],  # 2nd: 2 parents
    )
    (problem,) = add_tf_message(history, mixed, "/tf")
    assert "/tf map → camera" in problem
    assert "already has the parent 'base_link' on /tf_static" in problem
    assert history.lookup("odom", "camera", 10)[0, 3] == pytest.approx(1.5)
    (broken,) = add_tf_message(history, NS(), "/tf")
    assert broken.startswith("TFMessage on /tf: message of type SimpleNamespace has no field")
