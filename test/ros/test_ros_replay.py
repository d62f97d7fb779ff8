"""The sample bag as a robot delivers it, over real ROS 2: equal to ``dispeval bag``, a lagging
summarizer counts its losses, ten times the recorded rate (needs ROS 2).

The harness and message builders: ros_nodes_support.py.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ros_nodes_support import (
    convert,
    diagnostic_msgs,
    evaluator_node,
    evaluator_of,
    matched,
    rclpy,
    std_msgs,
    summarizer_node,
    summarizer_with_publisher,
    synthetic_scores,
)
from ros_support import Ros, input_types
from rosbags.typesys import Stores, get_typestore
from sample_feed import (
    Stream,
    bag_reference,
    expected_counts,
    robot_stream,
    sample_bag,
    sample_config,
)

from dispeval_ros.io.messages import stamp_ns
from dispeval_ros.io.store import MatchCounts, ResultsStore
from dispeval_ros.stream.core import EvaluationCore, MethodCounts
from dispeval_ros.stream.delivery import delivery_record, read_delivery
from dispeval_ros.stream.vectors import (
    scores_from_status,
    scores_status,
)


def play(
    publishers: dict[str, Any], stream: Stream, done: threading.Event, rate: float = 1.0
) -> None:
    """Publish the feed at its recorded timing (serialized CDR, as a bag player does)."""
    typestore = get_typestore(Stores.ROS2_JAZZY)
    payloads = [
        (topic, log_time, bytes(typestore.serialize_cdr(msg, msg.__msgtype__)))
        for topic, log_time, msg in stream
    ]
    first = min(log_time for _, log_time, _ in payloads)
    started = time.monotonic()
    try:
        for topic, log_time, payload in payloads:
            delay = started + (log_time - first) / 1e9 / rate - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            publishers[topic].publish(payload)
    finally:
        done.set()


def test_end_to_end_over_ros_equals_dispeval_bag(ros: Ros, tmp_path: Path) -> None:
    """Player → evaluator → summarizer and a subscriber, all real rclpy nodes and Fast DDS."""
    bag = sample_bag()
    config = sample_config(bag)
    stream, expected = robot_stream(bag, config)
    reference = bag_reference(bag, tmp_path / "bag")
    want = expected_counts(config, expected)
    # Compile (or load) the kernels first, as a node does on its first frame: a long compile
    # in the middle of the replay would only test the sensor-data history depth.
    warm = EvaluationCore(config)
    for topic, _, msg in stream[: 4 * len(config.topics)]:
        for frame_set in warm.push(topic, msg):
            warm.score(frame_set)

    out = tmp_path / "live"
    summarizer = ros.summarizer(output_dir=str(out), summary_every=5, drain_timeout=2.0)
    evaluator = evaluator_of(ros, config)
    sensor = rclpy.qos.qos_profile_sensor_data
    pubs = {t: ros.helper.create_publisher(k, t, sensor) for t, k in input_types(config).items()}
    scores = ros.collect(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", evaluator_node.SCORES_QOS
    )
    vectors = {
        m: ros.collect(
            std_msgs.Float64MultiArray, f"/dispeval/{m}/vector", evaluator_node.RESULTS_QOS
        )
        for m in config.methods
    }
    groups = ros.collect(
        diagnostic_msgs.DiagnosticArray, "/dispeval/groups", summarizer_node.GROUPS_QOS
    )
    assert ros.spin_until(matched(pubs, list(pubs)))
    assert ros.spin_until(lambda: evaluator._scores_pub.get_subscription_count() == 2)
    assert ros.spin_until(
        lambda: all(evaluator._vector_pubs[m].get_subscription_count() > 0 for m in vectors)
    )

    done = threading.Event()
    player = threading.Thread(target=play, args=(pubs, stream, done), daemon=True)
    player.start()
    assert ros.spin_until(done.is_set)
    player.join()
    ros.spin_for(0.3)  # the last messages in flight
    evaluator.finish()  # SIGINT: score what waits, publish, send the final counts

    def final_delivery() -> Any:
        for array in scores:
            for status in array.status:
                delivery = read_delivery(convert.status_record(status))
                if delivery is not None and delivery.final:
                    return delivery
        return None

    assert ros.spin_until(lambda: final_delivery() is not None)
    summarizer.finish(ros.executor)
    assert ros.spin_until(lambda: len(groups) >= 1)
    assert summarizer.groups_acknowledged

    # Published: every per-frame sum equals dispeval bag's; counts exactly as expected.
    final = final_delivery()
    assert final.counts == want
    published: dict[tuple[int, str], Any] = {}
    for array in scores:
        stamp = stamp_ns(array.header)
        for status in array.status:
            record = convert.status_record(status)
            if record.name in config.methods:
                published[stamp, record.name] = scores_from_status(record.values)
    assert len(published) == sum(c.matched for c in want.values())
    for key, method_scores in published.items():
        np.testing.assert_array_equal(method_scores.sums, reference[key].sums, err_msg=str(key))
    for method, received in vectors.items():
        assert len(received) == want[method].matched, method
    assert {status.name for status in groups[-1].status} == set(config.methods)

    # Stored: the same frames and sums, and the same counts as dispeval bag would store.
    ros.destroy(summarizer)
    with ResultsStore.open(out) as store:
        (sequence,) = store.sequences()
        stored = {
            (stamp, method): method_scores
            for stamp in store.stamps(sequence)
            for method, method_scores in store.frame_scores(sequence, stamp).items()
        }
        assert stored.keys() == published.keys()
        for key, method_scores in stored.items():
            np.testing.assert_array_equal(method_scores.sums, reference[key].sums)
        assert store.match_counts(sequence) == {
            m: MatchCounts(c.matched, c.unmatched, c.dropped, c.failed) for m, c in want.items()
        }
        assert store.problems() == []


def test_a_lagging_summarizer_counts_what_it_lost(ros: Ros, tmp_path: Path) -> None:
    """Arrays that never arrive (history overflow, lossy link) are counted, per method."""
    out = tmp_path / "results"
    node, publisher = summarizer_with_publisher(
        ros, output_dir=str(out), summary_every=1000, drain_timeout=0.0
    )
    frames = synthetic_scores(5)
    matched_so_far = {"good": 0, "bad": 0}
    for index, (stamp, frame) in enumerate(frames, start=1):
        matched_so_far = {m: n + 1 for m, n in matched_so_far.items()}
        counts = {m: MethodCounts(n, 0, 0, 0) for m, n in matched_so_far.items()}
        counts["never"] = MethodCounts(0, 4, 0, 0)
        if index in (2, 4):
            continue  # lost on the way
        records = [scores_status(m, f"/t/{m}", s, None, stamp) for m, s in frame.items()]
        records.append(delivery_record("ev", index, counts))
        publisher.publish(convert.diagnostic_array(stamp, records))
    final = {"good": MethodCounts(5, 0, 0, 0), "bad": MethodCounts(5, 0, 0, 0)}
    final["never"] = MethodCounts(0, 4, 0, 0)
    publisher.publish(convert.diagnostic_array(0, [delivery_record("ev", 5, final, final=True)]))
    assert ros.spin_until(lambda: node.frames_received == 4)
    ros.destroy(node)
    with ResultsStore.open(out) as store:
        (sequence,) = store.sequences()
        assert len(store.stamps(sequence)) == 3
        assert store.match_counts(sequence) == {
            "good": MatchCounts(3, 0, 2, 0),
            "bad": MatchCounts(3, 0, 2, 0),
            "never": MatchCounts(0, 4, 0, 0),
        }
        (problem,) = store.problems()
        assert problem.message.startswith("2 scored frame(s) of evaluator ev never reached")


def rss_bytes() -> int:
    """Resident memory of this process (Linux)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    return 0


@pytest.mark.slow
def test_overload_ten_times_the_recorded_rate_for_30_s(ros: Ros, tmp_path: Path) -> None:
    """The evaluator stays up with bounded memory; every scored frame is stored or counted."""
    bag = sample_bag()
    config = sample_config(bag)
    out = tmp_path / "results"
    summarizer = ros.summarizer(output_dir=str(out), summary_every=10, drain_timeout=2.0)
    evaluator = evaluator_of(
        ros,
        config,
        bag=str(bag),
        bag_rate=10.0,
        bag_loop=True,
        bag_wait_subscribers=1,
        bag_exit=False,
    )
    samples: list[int] = []
    started = time.monotonic()
    while time.monotonic() - started < 30.0:
        ros.spin_for(1.0)
        samples.append(rss_bytes())
    assert evaluator._replay_thread.is_alive(), "the replay stopped"
    evaluator.finish()
    counts = evaluator.counts()
    ros.spin_for(1.0)  # the final counts on their way
    ros.destroy(summarizer)  # drains what is still coming, stores, summarizes

    # memory: after the first third (caches, compiled kernels), no steady growth
    settled = max(samples[: len(samples) // 3])
    assert max(samples) < settled + 64 * 2**20, [s // 2**20 for s in samples]
    # every scored frame is in the database, or counted as lost (dropped) with a problem
    with ResultsStore.open(out) as store:
        stored: dict[str, MatchCounts] = {}
        for sequence in store.sequences():
            for method, c in store.match_counts(sequence).items():
                previous = stored.get(method, MatchCounts(0, 0, 0, 0))
                stored[method] = MatchCounts(
                    previous.matched + c.matched,
                    previous.unmatched + c.unmatched,
                    previous.dropped + c.dropped,
                    previous.failed + c.failed,
                )
        lost_messages = [p.message for p in store.problems() if "never reached" in p.message]
    assert set(stored) == set(config.methods)
    for method, c in counts.items():
        assert stored[method].matched + stored[method].dropped == c.matched + c.dropped, method
        assert stored[method].unmatched == c.unmatched, method
        assert stored[method].failed == c.failed, method
    lost = sum(stored[m].dropped - c.dropped for m, c in counts.items())
    assert (lost > 0) == bool(lost_messages)
    assert evaluator.published > 10 * 25, "not overloaded: fewer frames than ten passes"
    print(
        f"overload: {evaluator.published} arrays published, lost method-frames {lost}, "
        f"queue drops {evaluator._live.stats.queue_drops}, RSS {samples[0] // 2**20}→"
        f"{samples[-1] // 2**20} MiB"
    )


# -- robot mode: LiDAR ground truth -----------------------------------------------------------------
