"""The summarizer node in-process: it stores every frame, starts sequences on the service,
leaves problem statuses out (needs ROS 2).

The harness and message builders: ros_nodes_support.py.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from ros_nodes_support import (
    TIMEOUT,
    convert,
    diagnostic_msgs,
    std_srvs,
    summarizer_node,
    summarizer_with_publisher,
    synthetic_scores,
)
from ros_support import Ros

from dispeval_ros.io.store import ResultsStore
from dispeval_ros.stream.vectors import (
    problem_status,
    scores_status,
)


def scores_array(stamp: int, frame: dict[str, Any]) -> Any:
    records = [scores_status(m, f"/t/{m}", s, None, stamp) for m, s in frame.items()]
    return convert.diagnostic_array(stamp, records)


def test_summarizer_stores_every_frame_at_shutdown(ros: Ros, tmp_path: Path) -> None:
    out = tmp_path / "results"
    node = ros.summarizer(output_dir=str(out), summary_every=1000, drain_timeout=0.5)
    publisher = ros.helper.create_publisher(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", summarizer_node.SCORES_QOS
    )
    groups = ros.collect(
        diagnostic_msgs.DiagnosticArray, "/dispeval/groups", summarizer_node.GROUPS_QOS
    )
    assert ros.spin_until(lambda: publisher.get_subscription_count() > 0)
    frames = synthetic_scores(5)
    for stamp, frame in frames:
        publisher.publish(scores_array(stamp, frame))
    assert ros.spin_until(lambda: node.frames_received == 5)
    with ResultsStore.open(out) as store:  # fewer frames than summary_every: none stored yet
        assert store.stamps(node.sequence) == []

    node.finish(ros.executor)  # what SIGINT does: drain, store, summarize
    assert ros.spin_until(lambda: len(groups) >= 1)
    assert {status.name for status in groups[-1].status} == {"good", "bad"}
    sequence = node.sequence
    ros.destroy(node)

    with ResultsStore.open(out) as store:
        assert store.sequences() == [sequence]
        assert store.stamps(sequence) == [stamp for stamp, _ in frames]
        assert set(store.methods()) == {"good", "bad"}
        totals = store.sequence_scores(sequence)
    for method in ("good", "bad"):
        expected = np.sum([frame[method].sums for _, frame in frames], axis=0)
        np.testing.assert_allclose(totals[method].sums, expected, rtol=1e-12)
    assert (out / "summary.json").is_file()
    assert (out / "frames.csv").is_file()


def test_new_sequence_service_starts_a_sequence(ros: Ros, tmp_path: Path) -> None:
    out = tmp_path / "results"
    node = ros.summarizer(output_dir=str(out), summary_every=2, drain_timeout=0.0)
    publisher = ros.helper.create_publisher(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", summarizer_node.SCORES_QOS
    )
    client = ros.helper.create_client(std_srvs.Trigger, "/dispeval_summarizer/new_sequence")
    assert ros.spin_until(lambda: publisher.get_subscription_count() > 0)
    assert client.wait_for_service(timeout_sec=TIMEOUT)
    frames = synthetic_scores(4)
    first = node.sequence
    for stamp, frame in frames[:2]:
        publisher.publish(scores_array(stamp, frame))
    assert ros.spin_until(lambda: node.frames_received == 2)

    future = client.call_async(std_srvs.Trigger.Request())
    assert ros.spin_until(future.done)
    response = future.result()
    assert response.success, response.message
    second = node.sequence
    assert second != first

    for stamp, frame in frames[2:]:
        publisher.publish(scores_array(stamp, frame))
    assert ros.spin_until(lambda: node.frames_received == 4)
    ros.destroy(node)
    with ResultsStore.open(out) as store:
        assert store.sequences() == [first, second]
        assert store.stamps(first) == [stamp for stamp, _ in frames[:2]]
        assert store.stamps(second) == [stamp for stamp, _ in frames[2:]]


def test_problem_statuses_are_not_stored(ros: Ros, tmp_path: Path) -> None:
    out = tmp_path / "results"
    node, publisher = summarizer_with_publisher(
        ros, output_dir=str(out), summary_every=1, drain_timeout=0.0
    )
    ((stamp, frame),) = synthetic_scores(1)
    records = [scores_status("good", "/t/good", frame["good"], None, stamp)]
    records.append(problem_status("bad", "/t/bad", "/t/bad at 0: size mismatch"))
    publisher.publish(convert.diagnostic_array(stamp, records))
    assert ros.spin_until(lambda: node.frames_received == 1)
    ros.destroy(node)
    with ResultsStore.open(out) as store:
        assert store.methods() == ["good"]


# -- end to end: the sample bag as a robot delivers it, over real ROS 2 -------------------------
