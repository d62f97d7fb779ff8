"""The evaluator node with ``temporal``: each frame's statuses on ``/dispeval/scores`` carry
the pair ending there, exactly the core's (needs ROS 2; the harness: ros_nodes_support.py)."""

from __future__ import annotations

import numpy as np
from ros_nodes_support import (
    START_NS,
    Topics,
    camera_info_msg,
    diagnostic_msgs,
    evaluator_node,
    frame_messages,
    matched,
    publishers,
    statuses,
)
from ros_support import Ros

from dispeval_ros.ros import convert
from dispeval_ros.stream.core import EvaluationCore, FrameResult
from dispeval_ros.stream.vectors import PAIR_PREFIX, pair_from_status


def test_the_scores_statuses_carry_the_cores_pairs(ros: Ros) -> None:
    topics = Topics("pairs")
    node = ros.evaluator(
        methods=[f"good:{topics.good}", f"bad:{topics.bad}"],
        gt_topic=topics.gt,
        left_camera_info=topics.left,
        right_camera_info=topics.right,
        temporal="dispeval",
    )
    assert node.config.temporal == "dispeval"
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
    for k in range(3):
        for topic, msg in frame_messages(topics, k):
            pubs[topic].publish(msg)
            expected += [core.pair(core.score(s)) for s in core.push(topic, msg)]
        assert ros.spin_until(lambda k=k: len(scores) == k + 1), f"no scores for frame {k}"
    assert [bool(r.pairs) for r in expected] == [False, True, True]
    for array, result in zip(scores, expected, strict=True):
        got = statuses(array)
        for method in ("good", "bad"):
            values = convert.status_values(got[method])
            found = pair_from_status(values)
            if not result.pairs:
                assert found is None
                continue
            assert found is not None
            previous, pair = found
            assert previous == result.pair_previous
            np.testing.assert_array_equal(pair.sums, result.pairs[method].sums)
            table = dict(values)
            assert float(table[f"{PAIR_PREFIX}all/tepe"]) == result.pairs[method]["all"]["tepe"]
    good, bad = (expected[-1].pairs[m]["all"]["tepe"] for m in ("good", "bad"))
    assert bad > good  # 2 px of noise per frame flickers more than 0.3 px
