"""What the tests of the rclpy nodes share: the harness fixture, messages built with the rclpy
classes, publishers and the readers of what the nodes publish.

Messages are built with rclpy's generated classes (helpers mirroring the rosbags encoders of
``dispeval_ros.io.messages``). Importing this module skips the importing test module where rclpy
is not installed (outside a ROS 2 environment); ``colcon test`` runs them.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Callable
from typing import Any

import numpy as np
from ros_support import Ros, ros_import

from dispeval_ros.core import Camera, Evaluator
from dispeval_ros.core.measures import SEQUENCE_MEASURES
from dispeval_ros.stream.core import EvaluationCore, FrameResult
from dispeval_ros.stream.delivery import DELIVERY_STATUS, read_delivery
from dispeval_ros.stream.vectors import (
    OK,
    scores_from_status,
)

rclpy = ros_import("rclpy")
rclpy_context = ros_import("rclpy.context")
rclpy_executors = ros_import("rclpy.executors")
rclpy_parameter = ros_import("rclpy.parameter")
diagnostic_msgs = ros_import("diagnostic_msgs.msg")
rcl_interfaces = ros_import("rcl_interfaces.msg")
sensor_msgs = ros_import("sensor_msgs.msg")
std_msgs = ros_import("std_msgs.msg")
std_srvs = ros_import("std_srvs.srv")
stereo_msgs = ros_import("stereo_msgs.msg")

# Imported only now: they need rclpy (import errors in them must fail, not skip).
convert = importlib.import_module("dispeval_ros.ros.convert")
evaluator_node = importlib.import_module("dispeval_ros.ros.evaluator")
summarizer_node = importlib.import_module("dispeval_ros.ros.summarizer")

Parameter = rclpy_parameter.Parameter

DOMAIN_ID = 50 + os.getpid() % 50
"""A domain of its own, so that other ROS 2 processes on the machine do not interfere."""
TIMEOUT = 60.0
H, W = 48, 64
F, BASELINE = 100.0, 0.125
"""Exact in float32, so the DisparityImage's f and t give the CameraInfo pair's camera."""
FRAME_NS = 100_000_000
START_NS = 1_700_000_000_000_000_000


# -- harness ------------------------------------------------------------------------------------


def ros_harness() -> Ros:
    """A harness of its own domain with the node classes under test (the ``ros`` fixture's)."""
    return Ros(DOMAIN_ID, evaluator_node.EvaluatorNode, summarizer_node.SummarizerNode)


class Topics:
    """Input topics of one test (unique, so tests never see each other's messages)."""

    def __init__(self, name: str) -> None:
        base = f"/dispeval_test_{name}_{os.getpid()}"
        self.gt = f"{base}/ground_truth"
        self.left = f"{base}/left/camera_info"
        self.right = f"{base}/right/camera_info"
        self.good = f"{base}/good/disparity"
        self.bad = f"{base}/bad/disparity"


# -- messages built with the rclpy classes ---------------------------------------------------------


def gt_map(k: int) -> np.ndarray:
    """A slanted plane with a band of missing ground truth; a bit different every frame."""
    columns = np.arange(W, dtype=np.float32)
    gt = np.broadcast_to(8.0 + 0.25 * columns + k, (H, W)).astype(np.float32)
    gt[:, :6] = 0.0
    gt[H // 2 :, W // 2 : W // 2 + 8] += 10.0  # a nearer box: boundaries and occlusions
    return gt


def estimate(gt: np.ndarray, error: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    est = gt + rng.normal(0.0, error, gt.shape).astype(np.float32)
    est[:4, :] = -1.0  # stereo_image_proc's invalid marker (min_disparity - 1): missing
    return est.astype(np.float32)


def image_msg(array: np.ndarray, stamp: int, encoding: str = "32FC1") -> Any:
    return convert.image_msg(array, stamp, "stereo_left", encoding)


def disparity_msg(disparity: np.ndarray, stamp: int) -> Any:
    height, width = disparity.shape
    return stereo_msgs.DisparityImage(
        header=convert.header_msg(stamp, "stereo_left"),
        image=image_msg(disparity, stamp),
        f=F,
        t=BASELINE,
        valid_window=sensor_msgs.RegionOfInterest(
            x_offset=0, y_offset=0, height=height, width=width, do_rectify=False
        ),
        min_disparity=0.0,
        max_disparity=64.0,
        delta_d=1.0 / 16.0,
    )


def camera_info_msg(stamp: int, right: bool) -> Any:
    cx, cy = W / 2.0 - 0.5, H / 2.0 - 0.5
    tx = -F * BASELINE if right else 0.0
    return sensor_msgs.CameraInfo(
        header=convert.header_msg(stamp, "stereo_right" if right else "stereo_left"),
        height=H,
        width=W,
        distortion_model="plumb_bob",
        d=[0.0] * 5,
        k=np.array([F, 0.0, cx, 0.0, F, cy, 0.0, 0.0, 1.0]),
        r=np.eye(3).reshape(-1),
        p=np.array([F, 0.0, cx, tx, 0.0, F, cy, 0.0, 0.0, 0.0, 1.0, 0.0]),
        binning_x=0,
        binning_y=0,
        roi=sensor_msgs.RegionOfInterest(),
    )


def rig_camera_info(frame: Any, stamp: int, right: bool, frame_id: str = "stereo_left") -> Any:
    """The CameraInfo of a test-bed frame's left or right rectified camera (``P[3] = −f·B``)."""
    f, baseline = frame.camera.f, frame.camera.baseline
    cx, cy = frame.principal
    tx = -f * baseline if right else 0.0
    height, width = frame.left.shape[:2]
    return sensor_msgs.CameraInfo(
        header=convert.header_msg(stamp, "stereo_right" if right else frame_id),
        height=height,
        width=width,
        distortion_model="plumb_bob",
        d=[0.0] * 5,
        k=np.array([f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0]),
        r=np.eye(3).reshape(-1),
        p=np.array([f, 0.0, cx, tx, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0]),
    )


def frame_messages(topics: Topics, k: int, bad_shape: bool = False) -> list[tuple[str, Any]]:
    stamp = START_NS + k * FRAME_NS
    gt = gt_map(k)
    bad = estimate(gt, 2.0, 100 + k)
    if bad_shape:
        bad = bad[: H // 2]
    return [
        (topics.gt, image_msg(gt, stamp)),
        (topics.good, disparity_msg(estimate(gt, 0.3, k), stamp)),
        (topics.bad, disparity_msg(bad, stamp)),
    ]


def publishers(ros: Ros, topics: Topics) -> dict[str, Any]:
    types = {
        topics.gt: sensor_msgs.Image,
        topics.left: sensor_msgs.CameraInfo,
        topics.right: sensor_msgs.CameraInfo,
        topics.good: stereo_msgs.DisparityImage,
        topics.bad: stereo_msgs.DisparityImage,
    }
    return make_publishers(ros, types)


def make_publishers(ros: Ros, types: dict[str, Any]) -> dict[str, Any]:
    return {topic: ros.helper.create_publisher(kind, topic, 10) for topic, kind in types.items()}


def matched(pubs: dict[str, Any], topics: list[str]) -> Callable[[], bool]:
    return lambda: all(pubs[topic].get_subscription_count() > 0 for topic in topics)


def feed_node_and_core(
    ros: Ros, topics: Topics, node: Any, frames: int
) -> tuple[list[Any], list[FrameResult]]:
    """Publish the camera infos and ``frames`` frames to ``node``; its scores arrays, and what
    a core of its configuration fed the same messages gives (pairs and windows included)."""
    pubs = publishers(ros, topics)
    scores = ros.collect(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", evaluator_node.RESULTS_QOS
    )
    assert ros.spin_until(matched(pubs, list(pubs)))
    assert ros.spin_until(lambda: node._scores_pub.get_subscription_count() > 0)
    core = EvaluationCore(node.config)
    for topic, right in ((topics.left, False), (topics.right, True)):
        msg = camera_info_msg(START_NS, right)
        pubs[topic].publish(msg)
        core.push(topic, msg)
    assert ros.spin_until(lambda: node._live.core.camera() is not None)
    expected: list[FrameResult] = []
    for k in range(frames):
        for topic, msg in frame_messages(topics, k):
            pubs[topic].publish(msg)
            expected += [core.window(core.pair(core.score(s))) for s in core.push(topic, msg)]
        assert ros.spin_until(lambda k=k: len(scores) == k + 1), f"no scores for frame {k}"
    return scores, expected


def scores_once_matched(ros: Ros, node: Any, pubs: dict[str, Any], topics: list[str]) -> list[Any]:
    """The node's ``/dispeval/scores`` as they arrive, collected once ``topics``' publishers
    and the collector are matched with the node."""
    scores = ros.collect(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", evaluator_node.RESULTS_QOS
    )
    assert ros.spin_until(matched(pubs, topics))
    assert ros.spin_until(lambda: node._scores_pub.get_subscription_count() > 0)
    return scores


def statuses(array: Any) -> dict[str, Any]:
    """Method and problem statuses by name (the delivery record apart: see delivery_of)."""
    return {status.name: status for status in array.status if status.name != DELIVERY_STATUS}


def delivery_of(array: Any) -> Any:
    """The delivery record of a scores array (None if it has none)."""
    for status in array.status:
        if status.name == DELIVERY_STATUS:
            return read_delivery(convert.status_record(status))
    return None


# -- evaluator --------------------------------------------------------------------------------------


def synthetic_scores(frames: int) -> list[tuple[int, dict[str, Any]]]:
    evaluator = Evaluator(("all", "depth"), SEQUENCE_MEASURES)
    camera = Camera(F, BASELINE)
    result = []
    for k in range(frames):
        gt = gt_map(k)
        result.append(
            (
                START_NS + k * FRAME_NS,
                {
                    "good": evaluator.score(gt, estimate(gt, 0.3, k), camera=camera),
                    "bad": evaluator.score(gt, estimate(gt, 2.0, 100 + k), camera=camera),
                },
            )
        )
    return result


def evaluator_of(ros: Ros, config: Any, **parameters: Any) -> Any:
    """An evaluator node for the topics of a core configuration (and more parameters)."""
    return ros.evaluator(
        methods=[f"{m}:{t}" for m, t in config.methods.items()],
        gt_topic=config.gt_topic,
        left_camera_info=config.left_info_topic,
        right_camera_info=config.right_info_topic,
        **parameters,
    )


def summarizer_with_publisher(ros: Ros, **parameters: Any) -> tuple[Any, Any]:
    """A summarizer node and a publisher of /dispeval/scores it has matched."""
    node = ros.summarizer(**parameters)
    publisher = ros.helper.create_publisher(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", summarizer_node.SCORES_QOS
    )
    assert ros.spin_until(lambda: publisher.get_subscription_count() > 0)
    return node, publisher


def publish_frame(
    ros: Ros, pubs: dict[str, Any], core: EvaluationCore, scores: list[Any], messages: list[Any]
) -> list[FrameResult]:
    """Publish one frame's messages to the node and push them into ``core``; wait for its scores.

    Returns what the core scored for it.
    """
    before = len(scores)
    expected: list[FrameResult] = []
    for topic, msg in messages:
        pubs[topic].publish(msg)
        expected.extend(core.score(frame_set) for frame_set in core.push(topic, msg))
    assert ros.spin_until(lambda: len(scores) == before + 1), f"no scores for frame {before}"
    return expected


def statuses_against(
    scores: list[Any], expected: list[FrameResult], method: str
) -> list[tuple[Any, FrameResult]]:
    """Each published status of ``method`` with the core's result, their sums checked equal."""
    assert len(expected) == len(scores)
    pairs = []
    for array, result in zip(scores, expected, strict=True):
        status = statuses(array)[method]
        assert convert.status_level(status) == OK, status.message
        rebuilt = scores_from_status(convert.status_values(status))
        np.testing.assert_array_equal(rebuilt.sums, result.scores[method].sums)
        pairs.append((status, result))
    return pairs
