"""The evaluator node with ``flicker``: the ``/dispeval/scores`` status of the frame that closes
a window carries it, exactly the core's; the summarizer node stores every window it receives,
the one closed at the end on a status of its own too (needs ROS 2; the harness:
ros_nodes_support.py)."""

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
from dispeval_ros.stream.vectors import flicker_from_status, result_statuses


def test_the_scores_statuses_carry_the_cores_windows(ros: Ros) -> None:
    topics = Topics("flicker")
    node = ros.evaluator(
        methods=[f"good:{topics.good}", f"bad:{topics.bad}"],
        gt_topic=topics.gt,
        left_camera_info=topics.left,
        right_camera_info=topics.right,
        flicker=2,
    )
    assert node.config.flicker == 2
    scores, expected = feed_node_and_core(ros, topics, node, 4)
    assert [len(r.flicker) for r in expected] == [0, 2, 0, 2]
    for array, result in zip(scores, expected, strict=True):
        got = statuses(array)
        windows = {w.method: w for w in result.flicker}
        for method in ("good", "bad"):
            found = flicker_from_status(method, convert.status_values(got[method]))
            if method not in windows:
                assert found is None
                continue
            assert found is not None
            assert (found.start, found.stamp, found.frames) == (
                windows[method].start, windows[method].stamp, 2,
            )  # fmt: skip
            np.testing.assert_array_equal(found.sums.sums, windows[method].sums.sums)
    good, bad = (expected[-1].flicker[i].sums.summary("all")["mean"] for i in (0, 1))
    assert bad > good  # 2 px of noise per frame flickers more than 0.3 px


def test_the_summarizer_node_stores_every_window_it_receives(ros: Ros, tmp_path: Path) -> None:
    """Windows of 3 over 5 frames: one closes with frame 2, the last (2 frames) at the end."""
    topics = Topics("flicker_summarizer")
    config = CoreConfig(
        methods={"good": topics.good, "bad": topics.bad},
        gt_topic=topics.gt,
        left_info_topic=topics.left,
        right_info_topic=topics.right,
        flicker=3,
    )
    core = EvaluationCore(config)
    for topic, right in ((topics.left, False), (topics.right, True)):
        core.push(topic, camera_info_msg(START_NS, right))
    results: list[FrameResult] = []
    for k in range(5):
        for topic, msg in frame_messages(topics, k):
            results += [core.window(core.pair(core.score(s))) for s in core.push(topic, msg)]
    tail = core.finish_windows()
    assert tail is not None
    results.append(FrameResult(results[-1].stamp + 1, {}, {}, flicker=tail.windows))
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
        stored = store.flicker(sequence)
        assert store.problems(sequence) == []
    assert stored is not None
    for method in ("good", "bad"):
        parts = [w.sums.sums for r in results for w in r.flicker if w.method == method]
        assert stored[method][:2] == (len(parts), 5) == (2, 5)
        np.testing.assert_array_equal(stored[method][2].sums, np.sum(parts, axis=0))
