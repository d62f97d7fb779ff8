"""The evaluator node with ``temporal``: each frame's statuses on ``/dispeval/scores`` carry
the pair ending there, exactly the core's; the summarizer node stores what they carry (needs
ROS 2; the harness: ros_nodes_support.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from ros_nodes_support import (
    START_NS,
    Topics,
    camera_info_msg,
    diagnostic_msgs,
    feed_node_and_core,
    frame_messages,
    statuses,
    summarizer_node,
)
from ros_support import Ros

from dispeval_ros.io.store import ResultsStore
from dispeval_ros.ros import convert
from dispeval_ros.stream.core import CoreConfig, EvaluationCore, FrameResult
from dispeval_ros.stream.vectors import PAIR_PREFIX, pair_from_status, result_statuses


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
    scores, expected = feed_node_and_core(ros, topics, node, 3)
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


def test_the_summarizer_node_stores_the_pairs_it_receives(ros: Ros, tmp_path: Path) -> None:
    """Statuses with pairs → the summarizer node → its database: the pairs pooled exactly."""
    topics = Topics("pairs_summarizer")
    config = CoreConfig(
        methods={"good": topics.good, "bad": topics.bad},
        gt_topic=topics.gt,
        left_info_topic=topics.left,
        right_info_topic=topics.right,
        temporal="dispeval",
    )
    core = EvaluationCore(config)
    for topic, right in ((topics.left, False), (topics.right, True)):
        core.push(topic, camera_info_msg(START_NS, right))
    results: list[FrameResult] = []
    for k in range(4):
        for topic, msg in frame_messages(topics, k):
            results += [core.pair(core.score(s)) for s in core.push(topic, msg)]
    out = tmp_path / "results"
    node = ros.summarizer(output_dir=str(out), summary_every=1000, drain_timeout=0.5)
    publisher = ros.helper.create_publisher(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", summarizer_node.SCORES_QOS
    )
    assert ros.spin_until(lambda: publisher.get_subscription_count() > 0)
    for result in results:
        records = result_statuses(result, config.methods)
        publisher.publish(convert.diagnostic_array(result.stamp, records))
    assert ros.spin_until(lambda: node.frames_received == len(results))
    node.finish(ros.executor)
    sequence = node.sequence
    ros.destroy(node)
    with ResultsStore.open(out) as store:
        stored = store.pairs(sequence)
    assert stored is not None
    for method in ("good", "bad"):
        parts = [r.pairs[method].sums for r in results if method in r.pairs]
        assert stored[method].pairs == len(parts) == 3
        np.testing.assert_array_equal(stored[method].sums, np.sum(parts, axis=0))
