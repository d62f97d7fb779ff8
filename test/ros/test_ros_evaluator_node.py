"""The evaluator node in-process: its ``/dispeval/scores`` equal the core's to the last bit,
problems are error statuses, shutdown scores the waiting frames (needs ROS 2).

The harness and message builders: ros_nodes_support.py.
"""

from __future__ import annotations

import json

import numpy as np
from ros_nodes_support import (
    START_NS,
    Topics,
    camera_info_msg,
    convert,
    delivery_of,
    diagnostic_msgs,
    evaluator_node,
    frame_messages,
    matched,
    publishers,
    scores_once_matched,
    sensor_msgs,
    statuses,
    std_msgs,
)
from ros_support import Ros

from dispeval_ros.io.messages import image_from_msg, stamp_ns
from dispeval_ros.stream.core import EvaluationCore, FrameResult
from dispeval_ros.stream.images import colour_error
from dispeval_ros.stream.vectors import (
    ARRIVAL_KEY,
    DELAY_KEY,
    ERROR,
    ESTIMATE_STAMP_KEY,
    OK,
    PROBLEM_KEY,
    AlarmThresholds,
    score_vector,
    scores_from_status,
    scores_status,
    vector_labels,
)


def test_scores_vectors_and_error_images_equal_the_core(ros: Ros) -> None:
    topics = Topics("scores")
    node = ros.evaluator(
        methods=[f"good:{topics.good}", f"bad:{topics.bad}"],
        gt_topic=topics.gt,
        left_camera_info=topics.left,
        right_camera_info=topics.right,
        error_images=True,
    )
    pubs = publishers(ros, topics)
    scores = ros.collect(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", evaluator_node.RESULTS_QOS
    )
    vectors = ros.collect(
        std_msgs.Float64MultiArray, "/dispeval/good/vector", evaluator_node.RESULTS_QOS
    )
    labels = ros.collect(
        std_msgs.String, "/dispeval/good/vector_labels", evaluator_node.LATCHED_QOS
    )
    errors = ros.collect(sensor_msgs.Image, "/dispeval/bad/error", evaluator_node.RESULTS_QOS)
    colours = ros.collect(
        sensor_msgs.Image, "/dispeval/bad/error_color", evaluator_node.RESULTS_QOS
    )
    assert ros.spin_until(matched(pubs, list(pubs)))
    assert ros.spin_until(
        lambda: all(
            pub.get_subscription_count() > 0
            for pub in (
                node._scores_pub,
                node._vector_pubs["good"],
                node._error_pubs["bad"],
                node._colour_pubs["bad"],
            )
        )
    )

    core = EvaluationCore(node.config, error_images=True)
    infos = [(topics.left, camera_info_msg(START_NS, False))]
    infos.append((topics.right, camera_info_msg(START_NS, True)))
    for topic, msg in infos:
        pubs[topic].publish(msg)
        core.push(topic, msg)
    # Until both CameraInfo messages are in, the evaluator would score without a camera.
    assert ros.spin_until(lambda: node._live.core.camera() is not None)
    assert node._live.core.camera() == core.camera()

    expected: list[FrameResult] = []
    for k in range(3):
        for topic, msg in frame_messages(topics, k):
            pubs[topic].publish(msg)
            expected.extend(core.score(frame_set) for frame_set in core.push(topic, msg))
        assert ros.spin_until(lambda k=k: len(scores) == k + 1), f"no scores for frame {k}"
    assert ros.spin_until(lambda: len(vectors) == 3 and len(errors) == 3 and len(colours) == 3)
    assert ros.spin_until(lambda: len(labels) >= 1)
    assert len(expected) == 3

    no_alarms = AlarmThresholds()
    for index, (array, result) in enumerate(zip(scores, expected, strict=True), start=1):
        assert stamp_ns(array.header) == result.stamp
        got = statuses(array)
        delivery = delivery_of(array)
        assert delivery is not None
        assert (delivery.source, delivery.index, delivery.final) == (node.source_id, index, False)
        assert set(delivery.counts) == {"good", "bad"}
        assert set(got) == {"good", "bad"}
        for method, method_scores in result.scores.items():
            record = scores_status(
                method,
                node.config.methods[method],
                method_scores,
                no_alarms,
                result.estimate_stamps[method],
            )
            status = got[method]
            assert convert.status_level(status) == record.level == OK
            assert status.hardware_id == record.hardware_id
            assert status.message == record.message
            values = convert.status_values(status)  # exact numbers; the node's receipt beside
            timed = (ARRIVAL_KEY, DELAY_KEY)
            assert [item for item in values if item[0] not in timed] == list(record.values)
            assert [key for key, _ in values if key in timed] == list(timed)
            rebuilt = scores_from_status(convert.status_values(status))
            np.testing.assert_array_equal(rebuilt.sums, method_scores.sums)

    good_scores = expected[-1].scores["good"]
    names = vector_labels(good_scores.criteria, good_scores.measures)
    assert json.loads(labels[-1].data) == names
    layout = vectors[-1].layout
    assert [(d.label, d.size, d.stride) for d in layout.dim] == [
        (convert.VECTOR_DIM_LABEL, len(names), len(names))
    ]
    assert layout.data_offset == 0
    np.testing.assert_array_equal(
        np.asarray(vectors[-1].data), np.asarray(score_vector(good_scores, names))
    )

    for error_msg, colour_msg, result in zip(errors, colours, expected, strict=True):
        assert stamp_ns(error_msg.header) == result.stamp
        assert error_msg.encoding == "32FC1"
        np.testing.assert_array_equal(image_from_msg(error_msg).array, result.errors["bad"])
        assert colour_msg.encoding == "rgb8"
        assert result.partition is not None
        np.testing.assert_array_equal(
            image_from_msg(colour_msg).array, colour_error(result.errors["bad"], result.partition)
        )


def test_frame_problems_are_error_statuses(ros: Ros) -> None:
    topics = Topics("problems")
    node = ros.evaluator(methods=[f"good:{topics.good}", f"bad:{topics.bad}"], gt_topic=topics.gt)
    pubs = publishers(ros, topics)
    scores = scores_once_matched(ros, node, pubs, [topics.gt, topics.good, topics.bad])
    for topic, msg in frame_messages(topics, 0, bad_shape=True):
        pubs[topic].publish(msg)
    assert ros.spin_until(lambda: len(scores) == 1)
    got = statuses(scores[0])
    assert convert.status_level(got["good"]) == OK
    problem = got["bad"]
    assert convert.status_level(problem) == ERROR
    assert problem.hardware_id == topics.bad
    (key, text), *timing = convert.status_values(problem)
    assert key == PROBLEM_KEY
    assert [name for name, _ in timing] == [ESTIMATE_STAMP_KEY, ARRIVAL_KEY, DELAY_KEY]
    assert text == problem.message
    assert topics.bad in text
    node.finish()
    counts = node.counts()
    assert (counts["bad"].failed, counts["bad"].matched) == (1, 0)
    assert (counts["good"].failed, counts["good"].matched) == (0, 1)


def test_shutdown_scores_and_publishes_the_frames_still_waiting(ros: Ros) -> None:
    topics = Topics("flush")
    node = ros.evaluator(
        methods=[f"good:{topics.good}", f"bad:{topics.bad}"], gt_topic=topics.gt, lateness=600.0
    )
    pubs = publishers(ros, topics)
    scores = scores_once_matched(ros, node, pubs, [topics.gt, topics.good])
    gt, good, _ = frame_messages(topics, 0)
    for topic, msg in (gt, good):  # "bad" never delivers: the frame waits for it
        pubs[topic].publish(msg)
    assert ros.spin_until(lambda: node.counts()["good"].matched == 1)
    ros.spin_for(0.5)
    assert scores == []

    node.finish()  # what SIGINT does: flush, score, publish, then the final counts
    assert ros.spin_until(lambda: len(scores) == 2)
    assert set(statuses(scores[0])) == {"good"}
    assert delivery_of(scores[0]) is not None
    counts = node.counts()
    assert (counts["good"].matched, counts["bad"].dropped) == (1, 1)
    assert node.frames_scored == 1
    assert statuses(scores[1]) == {}
    final = delivery_of(scores[1])
    assert final is not None
    assert (final.index, final.final) == (1, True)
    assert final.counts["good"].matched == 1
    assert final.counts["bad"].dropped == 1
