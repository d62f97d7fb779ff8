"""Cross-vendor interop: the Cyclone DDS front ends and rclpy on Fast DDS, on loopback only.

- ``dispeval play --transport dds`` (Cyclone DDS) → an rclpy subscriber (Fast DDS): every
  message arrives with the recorded bytes;
- an rclpy publisher (Fast DDS) → ``dispeval live --transport dds`` (Cyclone DDS), whose
  ``/dispeval/scores`` an rclpy subscriber receives: every score equals ``dispeval bag``'s,
  bit for bit.

Each test has a domain of its own; discovery stays on this machine
(``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` for rclpy, the shipped localhost Cyclone
configuration for dispeval).
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import signal
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ros_support import ROS_REQUIRED, Ros, ros_import
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
from sample_feed import (
    bag_reference,
    dispeval_process,
    sample_bag,
    sample_config,
    topic_args,
)

from dispeval_ros.io.messages import stamp_ns
from dispeval_ros.offline.make_bag import GT_TOPIC, LEFT_INFO, RIGHT_INFO

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")  # before rclpy.init
rclpy = ros_import("rclpy")
rclpy_qos = ros_import("rclpy.qos")
diagnostic_msgs = ros_import("diagnostic_msgs.msg")
sensor_msgs = ros_import("sensor_msgs.msg")
stereo_msgs = ros_import("stereo_msgs.msg")
convert = importlib.import_module("dispeval_ros.ros.convert")
evaluator_node = importlib.import_module("dispeval_ros.ros.evaluator")
summarizer_node = importlib.import_module("dispeval_ros.ros.summarizer")

HAVE_CYCLONE = importlib.util.find_spec("cyclonedds") is not None
NO_CYCLONE = "the Cyclone DDS Python binding is not installed (pip install 'dispeval_ros[dds]')"
# A marker, never a skip while importing: in a ROS 2 workspace launch_testing's pytest plugin
# imports every test module, and a skip there would end the collection of every test.
pytestmark = pytest.mark.skipif(not HAVE_CYCLONE and not ROS_REQUIRED, reason=NO_CYCLONE)

TIMEOUT = 90.0
RELIABLE = rclpy_qos.QoSProfile(
    history=rclpy_qos.HistoryPolicy.KEEP_LAST,
    depth=1000,
    reliability=rclpy_qos.ReliabilityPolicy.RELIABLE,
    durability=rclpy_qos.DurabilityPolicy.VOLATILE,
)


def domain(offset: int) -> int:
    """A domain for this test alone (other test modules use 1–200 and 50–99)."""
    return 201 + (os.getpid() * 7 + offset) % 30


@pytest.fixture
def ros_factory() -> Iterator[Any]:
    if not HAVE_CYCLONE:
        pytest.fail(f"DISPEVAL_REQUIRE_ROS=1 but {NO_CYCLONE}", pytrace=False)
    made: list[Ros] = []

    def make(domain_id: int) -> Ros:
        harness = Ros(domain_id, evaluator_node.EvaluatorNode, summarizer_node.SummarizerNode)
        made.append(harness)
        return harness

    try:
        yield make
    finally:
        for harness in made:
            harness.close()


def dds_args(domain_id: int) -> list[str]:
    """The DDS domain of a test, and loopback only."""
    return ["--domain-id", str(domain_id), "--dds-config", "localhost"]


def stop(process: subprocess.Popen[bytes] | None) -> None:
    if process is not None and process.poll() is None:
        process.kill()
        process.wait()


def recorded_bytes(bag: Path, topics: list[str]) -> dict[str, list[bytes]]:
    """Every message of ``topics`` as the bag stores it (CDR), in recorded order."""
    found: dict[str, list[bytes]] = {topic: [] for topic in topics}
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic in found]
        for connection, _, raw in reader.messages(connections=connections):
            found[connection.topic].append(bytes(raw))
    return found


def wait_for(condition: Any, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.05)
    return bool(condition())


def test_dds_player_to_rclpy_subscriber_is_byte_exact(ros_factory: Any, tmp_path: Path) -> None:
    bag = sample_bag()
    config = sample_config(bag)
    topics = list(config.topics)
    types = {
        GT_TOPIC: sensor_msgs.Image,
        LEFT_INFO: sensor_msgs.CameraInfo,
        RIGHT_INFO: sensor_msgs.CameraInfo,
        **dict.fromkeys(config.methods.values(), stereo_msgs.DisparityImage),
    }
    expected = recorded_bytes(bag, topics)
    domain_id = domain(0)
    ros = ros_factory(domain_id)
    received = {t: ros.collect(types[t], t, RELIABLE, raw=True) for t in topics}
    log = tmp_path / "play.log"
    play = dispeval_process(
        "play",
        str(bag),
        "--topics",
        *topics,
        "--wait-matched",
        "60",
        "--quiet",
        *dds_args(domain_id),
        log=log,
    )
    try:
        total = sum(len(v) for v in expected.values())
        ros.spin_until(lambda: sum(len(v) for v in received.values()) >= total, TIMEOUT)
        assert play.wait(timeout=TIMEOUT) == 0, log.read_text(errors="replace")
    finally:
        stop(play)
    for topic in topics:
        got = [bytes(b) for b in received[topic]]
        assert len(got) == len(expected[topic]), topic
        for sent, recorded in zip(got, expected[topic], strict=True):
            # the recorded CDR, byte for byte; DDS pads a payload to a multiple of 4 bytes
            assert sent[: len(recorded)] == recorded, topic
            assert sent[len(recorded) :] == bytes(-len(recorded) % 4), topic


def test_rclpy_publisher_to_dds_live_to_rclpy_subscriber(ros_factory: Any, tmp_path: Path) -> None:
    bag = sample_bag()
    config = sample_config(bag)
    reference = bag_reference(bag, tmp_path / "bag")
    domain_id = domain(1)
    ros = ros_factory(domain_id)
    sensor = rclpy_qos.qos_profile_sensor_data
    types = {
        GT_TOPIC: sensor_msgs.Image,
        LEFT_INFO: sensor_msgs.CameraInfo,
        RIGHT_INFO: sensor_msgs.CameraInfo,
        **dict.fromkeys(config.methods.values(), stereo_msgs.DisparityImage),
    }
    pubs = {t: ros.helper.create_publisher(k, t, sensor) for t, k in types.items()}
    scores = ros.collect(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", evaluator_node.SCORES_QOS
    )
    log = tmp_path / "live.log"
    live = dispeval_process(
        "live",
        *topic_args(config),
        "--out",
        str(tmp_path / "live"),
        "--queue-size",
        "64",
        "--quiet",
        *dds_args(domain_id),
        log=log,
    )
    try:
        assert wait_for(lambda: "listening on" in log.read_text(errors="replace"), TIMEOUT), (
            log.read_text(errors="replace")
        )
        assert ros.spin_until(
            lambda: all(p.get_subscription_count() > 0 for p in pubs.values()), TIMEOUT
        ), "dispeval live's subscriptions were not discovered"
        # ... and live sees our publishers (discovery is not symmetric in time)
        assert ros.spin_until(
            lambda: "every input topic has a publisher" in log.read_text(errors="replace"),
            TIMEOUT,
        ), log.read_text(errors="replace")
        stream = []
        typestore = get_typestore(Stores.ROS2_JAZZY)
        with AnyReader([bag]) as reader:
            connections = [c for c in reader.connections if c.topic in pubs]
            for connection, log_time, raw in reader.messages(connections=connections):
                stream.append((connection.topic, log_time, bytes(raw)))
        first = stream[0][1]
        started = time.monotonic()
        gt_stamps = set()
        for topic, log_time, raw in stream:
            delay = started + (log_time - first) / 1e9 - time.monotonic()
            if delay > 0:
                ros.spin_for(delay)
            pubs[topic].publish(raw)
            if topic == GT_TOPIC:
                msg = typestore.deserialize_cdr(raw, "sensor_msgs/msg/Image")
                gt_stamps.add(stamp_ns(msg.header))

        def settled() -> bool:
            before = len(scores)
            ros.spin_for(1.0)
            return len(scores) == before and before > 0

        ros.spin_until(settled, TIMEOUT)
        live.send_signal(signal.SIGINT)
        finished = threading.Event()
        threading.Thread(target=lambda: (live.wait(), finished.set()), daemon=True).start()
        ros.spin_until(finished.is_set, TIMEOUT)  # its last scores still arrive meanwhile
        assert live.returncode == 0, log.read_text(errors="replace")
        ros.spin_for(0.5)
    finally:
        stop(live)

    received: dict[tuple[int, str], Any] = {}
    for array in scores:
        stamp = stamp_ns(array.header)
        for status in array.status:
            record = convert.status_record(status)
            if record.name in config.methods:
                assert (stamp, record.name) not in received, "a frame was published twice"
                received[stamp, record.name] = record
    # best effort into live: allow a lost input frame or two, never a wrong number
    assert len({stamp for stamp, _ in received}) >= len(gt_stamps) - 2, len(received)
    scores_from_status = importlib.import_module("dispeval_ros.stream.vectors").scores_from_status
    for key, record in received.items():
        rebuilt = scores_from_status(record.values)
        np.testing.assert_array_equal(rebuilt.sums, reference[key].sums, err_msg=str(key))
