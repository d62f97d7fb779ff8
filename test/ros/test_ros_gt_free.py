"""Ground-truth-free measures from the rectified images in the evaluator node (needs ROS 2).

The harness and message builders: ros_nodes_support.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from ros_nodes_support import (
    FRAME_NS,
    START_NS,
    H,
    Topics,
    W,
    convert,
    disparity_msg,
    estimate,
    image_msg,
    make_publishers,
    publish_frame,
    scores_once_matched,
    sensor_msgs,
    statuses_against,
    stereo_msgs,
)
from ros_support import Ros

from dispeval_ros.stream.core import EvaluationCore, FrameResult
from dispeval_ros.stream.vectors import (
    scores_from_status,
)


def stereo_images(k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A textured left image, the right one warped from it by a slanted plane, its disparity."""
    rows, columns = np.mgrid[0:H, 0:W].astype(np.float64)
    disparity = 6.0 + 0.05 * columns + 0.5 * k

    def texture(x: np.ndarray) -> np.ndarray:
        return 128 + 60 * np.sin(0.45 * x + 0.3 * rows) + 30 * np.cos(0.21 * x - 0.5 * rows)

    left = np.clip(np.round(texture(columns)), 0, 255).astype(np.uint8)
    source = (columns + 6.0 + 0.5 * k) / (1 - 0.05)  # x with x − d(x) = u
    right = np.clip(np.round(texture(source)), 0, 255).astype(np.uint8)
    return left, right, disparity.astype(np.float32)


@pytest.mark.parametrize("with_gt", [True, False], ids=["beside-gt", "no-gt"])
def test_gt_free_measures_equal_the_core(ros: Ros, with_gt: bool) -> None:
    topics = Topics(f"images_{int(with_gt)}")
    left_topic, right_topic = f"{topics.gt}_left_image", f"{topics.gt}_right_image"
    right_view = f"{topics.good}_right"
    node = ros.evaluator(
        methods=[f"good:{topics.good}"],
        gt_topic=topics.gt if with_gt else "",
        gt_kind="disparity" if with_gt else "none",
        left_image_topic=left_topic,
        right_image_topic=right_topic,
        right_views=[f"good:{right_view}"],
    )
    assert node.config.gt_free
    types = {
        left_topic: sensor_msgs.Image,
        right_topic: sensor_msgs.Image,
        topics.good: stereo_msgs.DisparityImage,
        right_view: stereo_msgs.DisparityImage,
        **({topics.gt: sensor_msgs.Image} if with_gt else {}),
    }
    pubs = make_publishers(ros, types)
    scores = scores_once_matched(ros, node, pubs, list(pubs))
    core = EvaluationCore(node.config)
    expected: list[FrameResult] = []
    for k in range(3):
        stamp = START_NS + k * FRAME_NS
        left, right, disparity = stereo_images(k)
        messages = [
            (left_topic, image_msg(left, stamp, "mono8")),
            (right_topic, image_msg(right, stamp, "mono8")),
            (right_view, disparity_msg(np.roll(disparity, -6, axis=1), stamp)),
            (topics.good, disparity_msg(estimate(disparity, 0.3, k), stamp)),
        ]
        if with_gt:
            messages.insert(0, (topics.gt, image_msg(disparity, stamp)))
        expected += publish_frame(ros, pubs, core, scores, messages)
    for status, result in statuses_against(scores, expected, "good"):
        values = dict(convert.status_values(status))
        assert "gtfree:textured/vpe" in values
        assert "gtfree:all/sze" not in values  # GT measures stay off the gtfree: criteria
        assert ("all/vpe" in values) is False
        rebuilt = scores_from_status(convert.status_values(status))
        assert rebuilt["gtfree:all"]["vpe"] == result.scores["good"]["gtfree:all"]["vpe"]
        assert 0 < rebuilt["gtfree:all"]["lrc"] < 100
        assert ("all" in rebuilt.criteria) is with_gt
