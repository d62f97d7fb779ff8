"""The evaluator node's delays over real rclpy: a bag replayed by the node measures exactly what
``dispeval bag`` measures, a live feed what its publisher sent (within the loopback's transit),
sim time the node's /clock (needs ROS 2).

No test asserts a timing: the live bound (:data:`LOOPBACK_BOUND_NS`) is far above the transit
measured here, it only tells a receipt on the stamps' clock from a wrong clock (seconds to
years off). The measured transit is printed (``pytest -s``) and written in the README.
"""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
from ros_nodes_support import (
    Topics,
    camera_info_msg,
    convert,
    delivery_of,
    diagnostic_msgs,
    disparity_msg,
    estimate,
    evaluator_node,
    evaluator_of,
    frame_messages,
    gt_map,
    image_msg,
    publishers,
    rclpy,
    scores_once_matched,
    sensor_msgs,
    statuses,
    stereo_msgs,
)
from ros_support import Ros, ros_import
from sample_feed import bag_reference, sample_bag, sample_config

from dispeval_ros.io.messages import image_from_msg, stamp_ns
from dispeval_ros.io.store import TIMING_JSON, ResultsStore
from dispeval_ros.stream.core import CoreConfig, EvaluationCore
from dispeval_ros.stream.vectors import DELAY_KEY, arrivals_of

rosgraph_msgs = ros_import("rosgraph_msgs.msg")

MS = 1_000_000
FRAMES = 50
PERIOD = 0.05
"""s between frames of the live feed (20 Hz)."""
PAST_NS = 200 * MS
"""How far in the past the second feed stamps its messages."""
LOOPBACK_BOUND_NS = 1000 * MS
"""Upper bound of receipt − send on one machine's loopback, with the executor's latency: the
transit measured here is below 10 ms (README, 'What was tested'); the margin covers a loaded
machine. A receipt on a wrong clock is off by far more."""


def node_delays(scores: list[Any], methods: list[str]) -> dict[tuple[int, str], tuple[int, int]]:
    """(estimate stamp, method) → (estimate stamp, arrival) in every published status (those of
    estimates not scored included); each method status has them, and its ``_delay_ms``."""
    found: dict[tuple[int, str], tuple[int, int]] = {}
    for array in scores:
        for name, status in statuses(array).items():
            record = convert.status_record(status)
            arrivals = arrivals_of(record)
            if name in methods:
                assert name in arrivals, f"{name}: no arrival in the status"
                sent, arrival = arrivals[name]
                delay_ms = float(dict(record.values)[DELAY_KEY])
                assert abs(delay_ms - (arrival - sent) / MS) <= 1e-4 * max(1.0, abs(delay_ms))
            for method, timing in arrivals.items():
                assert method in methods
                found[timing[0], method] = timing
    return found


def final_delivery(scores: list[Any]) -> Any:
    for array in scores:
        delivery = delivery_of(array)
        if delivery is not None and delivery.final:
            return delivery
    return None


def test_a_replayed_bag_has_the_delays_of_dispeval_bag(ros: Ros, tmp_path: Path) -> None:
    """The node's replay passes each message's log time as its arrival: per frame and method
    the same estimate stamp and arrival as ``dispeval bag`` stores (on the wall clock they
    would be the replay's receipt times, long after the recording's), and the summarizer's
    ``timing.json`` holds the same numbers as the bag run's."""
    bag = sample_bag()
    config = sample_config(bag)
    bag_reference(bag, tmp_path / "bag")
    with ResultsStore.open(tmp_path / "bag") as store:
        (sequence,) = store.sequences()
        timing = store.timing(sequence)
    assert timing
    expected = {(t.estimate_stamp, m): (t.estimate_stamp, t.arrival) for m, ts in timing.items()
                for t in ts}  # fmt: skip
    assert len({a - s for s, a in expected.values()}) > 1, "the sample bag records delays"

    out = tmp_path / "live"
    summarizer = ros.summarizer(output_dir=str(out), drain_timeout=2.0)
    scores = ros.collect(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", evaluator_node.SCORES_QOS
    )
    node = evaluator_of(
        ros, config, bag=str(bag), bag_rate=0.0, bag_wait_subscribers=2, bag_exit=False
    )
    thread = node._replay_thread
    assert ros.spin_until(lambda: not thread.is_alive())
    node.finish()
    assert ros.spin_until(lambda: final_delivery(scores) is not None)

    published = node_delays(scores, list(config.methods))
    assert len(published) == sum(c.matched for c in final_delivery(scores).counts.values()) > 0
    assert published == {key: expected[key] for key in published}

    ros.destroy(summarizer)  # drains, stores, writes the files
    assert by_method(out / TIMING_JSON) == by_method(tmp_path / "bag" / TIMING_JSON)


def by_method(path: Path) -> dict[str, Any]:
    """A one-sequence ``timing.json``'s sections by method (the sequence names differ)."""
    document = json.loads(path.read_text())
    assert len({name.rpartition("/")[0] for name in document}) == 1, document.keys()
    return {name.rpartition("/")[2]: keys for name, keys in document.items()}


def _feed(
    ros: Ros, topics: Topics, past_ns: int, sent: dict[tuple[int, str], int], done: threading.Event
) -> None:
    """A publisher node's feed: each frame stamped ``past_ns`` before its clock's now; every
    estimate's send time (the clock just before its publish) recorded by (stamp, method)."""
    node = rclpy.create_node("dispeval_test_feed", context=ros.context)
    try:
        types = {topics.gt: sensor_msgs.Image}
        types.update(dict.fromkeys((topics.good, topics.bad), stereo_msgs.DisparityImage))
        pubs = {topic: node.create_publisher(kind, topic, 10) for topic, kind in types.items()}
        deadline = time.monotonic() + 30.0
        while any(p.get_subscription_count() == 0 for p in pubs.values()):
            assert time.monotonic() < deadline, "the evaluator never subscribed"
            time.sleep(0.01)
        clock = node.get_clock()
        for k in range(FRAMES):
            gt = gt_map(k)
            stamp = clock.now().nanoseconds - past_ns
            pubs[topics.gt].publish(image_msg(gt, stamp))
            for method, topic, error in (("good", topics.good, 0.3), ("bad", topics.bad, 2.0)):
                msg = disparity_msg(estimate(gt, error, k), stamp)
                sent[stamp, method] = clock.now().nanoseconds
                pubs[topic].publish(msg)
            time.sleep(PERIOD)
    finally:
        node.destroy_node()
        done.set()


def warm_kernels(topics: Topics) -> None:
    """Compile (or load) the kernels before the measured frames, as a node does on its first
    frame: a compile holds the GIL, the executor would receive late meanwhile."""
    core = EvaluationCore(CoreConfig(methods={"good": topics.good}, gt_topic=topics.gt))
    gt = gt_map(0)
    core.push(topics.gt, image_msg(gt, 1))
    for frame_set in core.push(topics.good, disparity_msg(gt, 1)):
        core.score(frame_set)


def live_delays(ros: Ros, name: str, past_ns: int) -> tuple[dict[Any, tuple[int, int]], dict]:
    """The node's (estimate stamp, arrival) and the feed's send times for one live run."""
    topics = Topics(name)
    warm_kernels(topics)
    node = ros.evaluator(methods=[f"good:{topics.good}", f"bad:{topics.bad}"], gt_topic=topics.gt)
    scores = ros.collect(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", evaluator_node.RESULTS_QOS
    )
    assert ros.spin_until(lambda: node._scores_pub.get_subscription_count() > 0)
    sent: dict[tuple[int, str], int] = {}
    done = threading.Event()
    feed = threading.Thread(target=_feed, args=(ros, topics, past_ns, sent, done), daemon=True)
    feed.start()
    assert ros.spin_until(done.is_set)
    feed.join()
    ros.spin_until(lambda: len(scores) == FRAMES, timeout=10.0)
    ros.destroy(node)  # scores what still waits (sensor-data QoS may drop a message)
    ros.spin_for(0.2)
    return node_delays(scores, ["good", "bad"]), sent


def check_live(found: dict[Any, tuple[int, int]], sent: dict, past_ns: int) -> list[float]:
    """Every delay is its receipt after the send (≥ 0, below the bound) plus ``past_ns``."""
    assert found.keys() <= sent.keys()
    assert len(found) >= FRAMES, "most estimates arrive on the loopback"
    transits = []
    for key, (stamp, arrival) in found.items():
        transit = arrival - sent[key]
        assert 0 <= transit < LOOPBACK_BOUND_NS, (key, transit)
        assert sent[key] - stamp >= past_ns
        delay = arrival - stamp
        assert past_ns <= delay < past_ns + LOOPBACK_BOUND_NS
        transits.append(transit / MS)
    return transits


def test_live_delays_are_receipt_minus_the_publisher_s_stamp(ros: Ros) -> None:
    """A publisher stamping at send gives delays from 0 to the bound; one stamping 200 ms in
    the past gives 200 ms more, each receipt still just after its send time."""
    now, sent_now = live_delays(ros, "latency_now", 0)
    past, sent_past = live_delays(ros, "latency_past", PAST_NS)
    transits = check_live(now, sent_now, 0) + check_live(past, sent_past, PAST_NS)
    median, p95 = np.percentile(transits, [50, 95])
    print(
        f"loopback receipt - send over {len(transits)} estimates: median {median:.3f} ms, "
        f"p95 {p95:.3f} ms, max {max(transits):.3f} ms"
    )


def test_sim_time_receipts_are_the_node_s_clock(ros: Ros) -> None:
    """With use_sim_time the receipt is /clock's time: a frame stamped 200 ms before it has a
    delay of exactly 200 ms; frames before the first /clock are refused, not scored at 0 (the
    CameraInfo pair sent then is kept: it needs no receipt time)."""
    topics = Topics("latency_sim")
    node = ros.evaluator(
        methods=[f"good:{topics.good}"],
        gt_topic=topics.gt,
        left_camera_info=topics.left,
        right_camera_info=topics.right,
        use_sim_time=True,
    )
    pubs = publishers(ros, topics)
    clock_pub = ros.helper.create_publisher(rosgraph_msgs.Clock, "/clock", 10)
    inputs = [topics.gt, topics.good, topics.left, topics.right]
    scores = scores_once_matched(ros, node, pubs, inputs)
    assert ros.spin_until(lambda: clock_pub.get_subscription_count() > 0)

    def frame(stamp: int) -> None:
        gt = gt_map(0)
        pubs[topics.gt].publish(image_msg(gt, stamp))
        pubs[topics.good].publish(disparity_msg(estimate(gt, 0.3, 0), stamp))

    def set_clock(ns: int) -> None:
        clock_pub.publish(rosgraph_msgs.Clock(clock=convert.header_msg(ns, "").stamp))
        assert ros.spin_until(lambda: node.get_clock().now().nanoseconds == ns)

    start = 1_000 * 1_000_000_000
    pubs[topics.left].publish(camera_info_msg(0, right=False))
    pubs[topics.right].publish(camera_info_msg(0, right=True))
    frame(start - 5 * PAST_NS)  # before any /clock: refused
    ros.spin_for(0.5)
    set_clock(start)
    frame(start - PAST_NS)
    assert ros.spin_until(lambda: len(scores) == 1)
    set_clock(start + 10 * PAST_NS)
    frame(start + 10 * PAST_NS - PAST_NS // 4)
    assert ros.spin_until(lambda: len(scores) == 2)
    found = node_delays(scores, ["good"])
    assert {stamp: arrival - stamp for stamp, arrival in found.values()} == {
        start - PAST_NS: PAST_NS,
        start + 10 * PAST_NS - PAST_NS // 4: PAST_NS // 4,
    }
    assert [stamp_ns(array.header) for array in scores] == sorted(s for s, _ in found.values())
    assert [set(statuses(array)) for array in scores] == [{"good"}, {"good"}]  # no problem
    assert node.counts()["good"].matched == 2
    assert node.counts()["good"].unmatched == 0


def test_failed_estimates_keep_their_arrivals(ros: Ros, tmp_path: Path) -> None:
    """An estimate that could not be scored was delivered: its arrival goes with its problem
    status (or the ground truth's) and the summarizer stores it, as ``dispeval bag`` does: on
    a frame where one method fails, where both do, and where the ground truth does."""
    topics = Topics("latency_failed")
    out = tmp_path / "live"
    summarizer = ros.summarizer(output_dir=str(out), drain_timeout=2.0)
    node = ros.evaluator(methods=[f"good:{topics.good}", f"bad:{topics.bad}"], gt_topic=topics.gt)
    pubs = publishers(ros, topics)
    scores = scores_once_matched(ros, node, pubs, [topics.gt, topics.good, topics.bad])
    assert ros.spin_until(lambda: node._scores_pub.get_subscription_count() == 2)
    frames = [frame_messages(topics, 0, bad_shape=True), frame_messages(topics, 1, bad_shape=True)]
    gt, (good_topic, good), bad = frames[1]
    half = disparity_msg(image_from_msg(good.image).array[: good.image.height // 2], 0)
    half.header = good.header  # frame 1: both estimates fail
    frames[1] = [gt, (good_topic, half), bad]
    frames.append(frame_messages(topics, 2))
    (gt_topic, gt), *estimates = frame_messages(topics, 3)  # frame 3: its ground truth fails
    colour = np.zeros((gt.height, gt.width, 3), np.uint8)
    frames.append([(gt_topic, image_msg(colour, stamp_ns(gt.header), "rgb8")), *estimates])
    for k, messages in enumerate(frames):
        for topic, msg in messages:
            pubs[topic].publish(msg)
        assert ros.spin_until(lambda k=k: len(scores) == k + 1)
    node.finish()
    assert ros.spin_until(lambda: final_delivery(scores) is not None)
    ros.destroy(summarizer)

    published = node_delays(scores, ["good", "bad"])
    stamps = [stamp_ns(array.header) for array in scores if statuses(array)]
    assert published.keys() == {(s, m) for s in stamps for m in ("good", "bad")}
    with ResultsStore.open(out) as store:
        (sequence,) = store.sequences()
        stored = {
            (t.estimate_stamp, m): (t.estimate_stamp, t.arrival)
            for m, ts in (store.timing(sequence) or {}).items()
            for t in ts
        }
        assert stored == published
        counts = store.match_counts(sequence)
        assert (counts["good"].failed, counts["bad"].failed) == (2, 3)
        assert [p.method for p in store.problems() if p.stamp == stamps[3]] == [None]
        assert sorted(store.stamps(sequence)) == [stamps[0], stamps[2]]
    assert set(by_method(out / TIMING_JSON)) == {"good", "bad"}
