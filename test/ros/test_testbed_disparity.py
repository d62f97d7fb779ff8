"""The test-bed disparity node over real rclpy, driven through its parameter services.

It has stereo_image_proc's interface (topics ``left/image_rect``, ``right/image_rect``, their
camera infos, ``disparity``; the same parameter names, ranges and defaults) and publishes what
OpenCV computes with its current parameters, bit for bit. :class:`RemoteParameters` sets them
as ``dispeval tune --node`` does (checked with GetParameters), restores them, and says in one
line what a node refuses, lacks, or a node that is not there (needs ROS 2).
"""

from __future__ import annotations

import itertools
from typing import Any

import cv2
import numpy as np
import pytest
from ros_nodes_support import convert, rig_camera_info, stereo_msgs
from ros_support import Ros, ros_import

from dispeval_ros.errors import ConfigurationError
from dispeval_ros.offline.make_bag import START_NS, synthetic_frames
from dispeval_ros.testbed.disparity_node import DisparityNodeModel, node_defaults

sensor_msgs = ros_import("sensor_msgs.msg")
testbed_disparity = ros_import("dispeval_ros.ros.testbed_disparity")
parameter_client = ros_import("dispeval_ros.ros.parameter_client")
qos = ros_import("rclpy.qos")

WIDTH, HEIGHT = 256, 96
_names = itertools.count()


@pytest.fixture(scope="module")
def frame() -> Any:
    (first,) = synthetic_frames(1, WIDTH, HEIGHT, 10.0, seed=3)
    return first


def start_node(ros: Ros) -> tuple[Any, str, list[Any]]:
    """A test-bed node in a namespace of its own, and what it publishes on ``disparity``."""
    namespace = f"/testbed_{next(_names)}"
    node = ros.add(testbed_disparity.TestbedDisparityNode(context=ros.context, namespace=namespace))
    received = ros.collect(stereo_msgs.DisparityImage, f"{namespace}/disparity", 1)
    return node, namespace, received


def publish_pair(ros: Ros, namespace: str, frame: Any, stamp: int) -> None:
    topics = {name: f"{namespace}/{name}" for name in testbed_disparity.INPUTS}
    messages = {
        "left/image_rect": convert.image_msg(frame.left, stamp, "stereo_left", "mono8"),
        "right/image_rect": convert.image_msg(frame.right, stamp, "stereo_left", "mono8"),
        "left/camera_info": rig_camera_info(frame, stamp, right=False),
        "right/camera_info": rig_camera_info(frame, stamp, right=True),
    }
    publishers = {}
    for name, topic in topics.items():
        kind = sensor_msgs.Image if name.endswith("image_rect") else sensor_msgs.CameraInfo
        publishers[name] = ros.helper.create_publisher(kind, topic, qos.qos_profile_sensor_data)
    assert ros.spin_until(lambda: all(p.get_subscription_count() for p in publishers.values()))
    for name, msg in messages.items():
        publishers[name].publish(msg)
    for publisher in publishers.values():
        ros.helper.destroy_publisher(publisher)


def opencv_bm_defaults(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """OpenCV's block matcher with the node's defaults, as stereo_image_proc publishes it."""
    bm = cv2.StereoBM.create(numDisparities=64, blockSize=15)
    bm.setPreFilterType(cv2.StereoBM_PREFILTER_XSOBEL)
    bm.setPreFilterSize(9)
    bm.setPreFilterCap(31)
    bm.setTextureThreshold(10)
    bm.setUniquenessRatio(15)
    bm.setSpeckleWindowSize(100)
    bm.setSpeckleRange(4)
    bm.setMinDisparity(0)
    raw = bm.compute(left, right)
    values = raw.astype(np.float32) / np.float32(16.0)
    values[raw < 0] = -1.0  # invalid: min_disparity − 1
    return values


def values_of(msg: Any) -> np.ndarray:
    return np.frombuffer(bytes(msg.image.data), "<f4").reshape(msg.image.height, msg.image.width)


def test_the_node_publishes_what_opencv_computes(ros: Ros, frame: Any) -> None:
    node, namespace, received = start_node(ros)
    assert ros.spin_until(lambda: node._publisher.get_subscription_count() > 0)
    publish_pair(ros, namespace, frame, START_NS)
    assert ros.spin_until(lambda: len(received) == 1)
    (msg,) = received
    np.testing.assert_array_equal(values_of(msg), opencv_bm_defaults(frame.left, frame.right))
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == divmod(START_NS, 10**9)
    assert msg.f == pytest.approx(frame.camera.f)
    assert msg.t == pytest.approx(frame.camera.baseline)
    assert (msg.min_disparity, msg.max_disparity, msg.delta_d) == (0.0, 63.0, 1.0 / 16.0)
    # the real node's valid window: left = range + min + border − 1, right = width − 1 − border
    border = 15 // 2
    window = msg.valid_window
    assert (window.x_offset, window.y_offset) == (64 + border - 1, border)
    assert (window.width, window.height) == (
        WIDTH - 1 - border - (64 + border - 1),
        HEIGHT - 1 - 2 * border,
    )


def test_parameters_set_through_the_services_reach_the_matcher(ros: Ros, frame: Any) -> None:
    node, namespace, received = start_node(ros)
    remote = parameter_client.RemoteParameters(
        ros.helper, f"{namespace}/disparity_node", ros.executor
    )
    remote.wait()
    before = remote.get(["stereo_algorithm", "correlation_window_size", "P1", "P2"])
    assert before == {
        "stereo_algorithm": 0,
        "correlation_window_size": 15,
        "P1": 200.0,
        "P2": 400.0,
    }
    chosen = {"stereo_algorithm": 1, "correlation_window_size": 5, "P1": 100.0, "P2": 900.0}
    remote.set(chosen)
    assert remote.get(chosen) == chosen
    assert ros.spin_until(lambda: node._publisher.get_subscription_count() > 0)
    publish_pair(ros, namespace, frame, START_NS + 1)
    assert ros.spin_until(lambda: len(received) == 1)
    model = DisparityNodeModel()
    model.update(chosen)
    expected = model.method().compute(frame.left, frame.right)
    np.testing.assert_array_equal(values_of(received[0]), expected)
    remote.restore()
    assert remote.get(before) == before


@pytest.mark.parametrize(
    ("values", "words"),
    [
        ({"correlation_window_size": 6}, "refused correlation_window_size = 6"),
        ({"disparity_range": 40}, "refused disparity_range = 40"),
        ({"stereo_algorithm": 1, "P1": 500.0, "P2": 400.0}, "P2 must be greater than P1"),
    ],
)
def test_a_refused_value_is_one_line_and_changes_nothing(
    ros: Ros, values: dict[str, Any], words: str
) -> None:
    _, namespace, _ = start_node(ros)
    remote = parameter_client.RemoteParameters(
        ros.helper, f"{namespace}/disparity_node", ros.executor
    )
    with pytest.raises(ConfigurationError, match=words):
        remote.set(values)
    assert remote.get(values) == {name: node_defaults()[name] for name in values}


def test_a_missing_parameter_or_node_is_one_line(ros: Ros) -> None:
    _, namespace, _ = start_node(ros)
    remote = parameter_client.RemoteParameters(
        ros.helper, f"{namespace}/disparity_node", ros.executor
    )
    with pytest.raises(ConfigurationError, match="has no parameter 'full_dp'"):
        remote.get(["full_dp"])
    nobody = parameter_client.RemoteParameters(
        ros.helper, "/no_such_node", ros.executor, timeout=0.5
    )
    with pytest.raises(ConfigurationError, match=r"no node /no_such_node: .* did not appear"):
        nobody.wait()
