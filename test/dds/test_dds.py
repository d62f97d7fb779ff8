"""The DDS front ends: ROS 2 wire conventions, the raw-CDR transport, live + play end to end.

The end-to-end test runs ``dispeval live`` and ``dispeval play`` as separate processes on the
loopback interface (the shipped localhost configuration, a domain derived from the pid), listens
to ``/dispeval/scores`` and ``/dispeval/groups`` here, and compares every frame with what
``dispeval bag`` stores for the same bag.
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bag_support import as_ros1
from rosbags.typesys import Stores, get_typestore
from sample_feed import dispeval_process

from dispeval_ros.cli.main import main
from dispeval_ros.dds import environment, wire
from dispeval_ros.dds.diagnostics import diagnostic_array, records_of, vector_message
from dispeval_ros.dds.diagnostics import header as diagnostics_header
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.encoders import disparity_to_msg, image_to_msg
from dispeval_ros.io.store import MatchCounts, ResultsStore
from dispeval_ros.offline.make_bag import (
    CLOUD_TOPIC,
    GT_TOPIC,
    LEFT_IMAGE,
    LEFT_INFO,
    RIGHT_IMAGE,
    RIGHT_INFO,
    START_NS,
    TF_STATIC_TOPIC,
)
from dispeval_ros.offline.sample import find_sample_bag
from dispeval_ros.stream.delivery import read_delivery
from dispeval_ros.stream.vectors import StatusRecord, scores_from_status

HAVE_DDS = importlib.util.find_spec("cyclonedds") is not None
needs_dds = pytest.mark.skipif(
    not HAVE_DDS,
    reason="the Cyclone DDS Python binding cannot be imported (pip install 'dispeval_ros[dds]')",
)

STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
IMAGE_HASH = "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47"
"""The hashes ROS 2 Jazzy announces for std_msgs/String and sensor_msgs/Image."""

DISPARITY = "stereo_msgs/msg/DisparityImage"
_domains = iter(range(200))


def fresh_domain() -> int:
    """A domain no other test (and, most likely, no other test run) uses."""
    return 1 + (os.getpid() * 13 + next(_domains)) % 200


def wait_until(condition: Callable[[], bool], timeout: float, step: float = 0.05) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(step)
    return condition()


@pytest.fixture
def localhost(monkeypatch: pytest.MonkeyPatch) -> Path:
    """This process uses the shipped same-host configuration."""
    config = environment.localhost_config()
    monkeypatch.setenv("CYCLONEDDS_URI", config.as_uri())
    return config


@pytest.fixture(scope="module")
def sample() -> Path:
    bag = find_sample_bag()
    assert bag is not None, "bags/sample_drive is part of the repository"
    return bag


@pytest.fixture(scope="module")
def methods(sample: Path) -> dict[str, str]:
    with BagSource(sample) as source:
        return {
            topic.split("/")[2]: topic
            for topic, info in source.topics.items()
            if info.msgtype == DISPARITY
        }


# -- the wire conventions (no DDS needed) -----------------------------------------------------


def test_topic_and_type_names() -> None:
    assert wire.dds_topic("/stereo/sgbm/disparity") == "rt/stereo/sgbm/disparity"
    assert wire.dds_topic("dispeval/scores") == "rt/dispeval/scores"
    assert wire.ros_topic("rt/stereo/sgbm/disparity") == "/stereo/sgbm/disparity"
    assert wire.ros_topic("DCPSPublication") is None
    assert wire.dds_type_name(DISPARITY) == "stereo_msgs::msg::dds_::DisparityImage_"
    assert wire.dds_type_name("std_msgs/String") == "std_msgs::msg::dds_::String_"
    assert wire.ros_type_name("diagnostic_msgs::msg::dds_::DiagnosticArray_") == (
        "diagnostic_msgs/msg/DiagnosticArray"
    )
    assert wire.ros_type_name("org::eclipse::cyclonedds::builtin::DCPSTopic") is None
    assert wire.vector_topic("sgbm_3way") == "/dispeval/sgbm_3way/vector"
    for bad in ("/a//b", "/a/", "/1a", "a b", "/a/b-c", ""):
        with pytest.raises(ConfigurationError):
            wire.dds_topic(bad)
    with pytest.raises(ConfigurationError, match="method name"):
        wire.vector_topic("sgbm-3way")


def test_type_hash_and_user_data() -> None:
    store = get_typestore(Stores.ROS2_HUMBLE)
    assert wire.type_hash(store, "std_msgs/msg/String") == STRING_HASH
    assert wire.type_hash(store, "sensor_msgs/msg/Image") == IMAGE_HASH
    data = wire.user_data(store, DISPARITY)
    assert data.startswith(b"typehash=RIHS01_")
    assert data.endswith(b";")
    assert len(data) == len("typehash=RIHS01_;") + 64
    assert wire.parse_user_data(data + b"enclave=/;") == {
        "typehash": wire.type_hash(store, DISPARITY),
        "enclave": "/",
    }
    with pytest.raises(ConfigurationError, match="nope"):
        wire.type_hash(store, "nope/msg/Nothing")


def test_padding_and_diagnostics_round_trip() -> None:
    assert wire.pad_cdr(b"\x00\x01\x00\x00ab") == b"\x00\x01\x00\x00ab\x00\x00"
    payload = b"\x00\x01\x00\x00abcd"
    assert wire.pad_cdr(payload) is payload
    store = get_typestore(Stores.ROS2_HUMBLE)
    records = [
        StatusRecord("sgbm", "/stereo/sgbm/disparity", 0, "ok", (("all/bmp", "12.5"),)),
        StatusRecord("ground_truth", "/gt", 2, "bad frame", ()),
    ]
    msg = diagnostic_array(store, 1_700_000_000_123_456_789, records)
    raw = store.serialize_cdr(msg, wire.DIAGNOSTIC_ARRAY)
    assert records_of(store.deserialize_cdr(raw, wire.DIAGNOSTIC_ARRAY)) == (
        1_700_000_000_123_456_789,
        records,
    )
    vector = vector_message(store, ["all/n", "all/bmp"], [10.0, math.nan])
    back = store.deserialize_cdr(
        store.serialize_cdr(vector, wire.FLOAT64_MULTI_ARRAY), wire.FLOAT64_MULTI_ARRAY
    )
    assert back.layout.dim[0].label == "all/n,all/bmp"
    assert back.data[0] == 10.0
    assert math.isnan(back.data[1])


def test_importing_dispeval_does_not_import_cyclonedds() -> None:
    code = (
        "import sys, dispeval_ros, dispeval_ros.cli.main, dispeval_ros.dds.wire;"
        "assert 'cyclonedds' not in sys.modules, 'cyclonedds imported'"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)


def test_missing_cyclonedds_is_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "cyclonedds", None)
    with pytest.raises(ConfigurationError) as caught:
        environment.require_cyclonedds()
    message = str(caught.value)
    assert "pip install 'dispeval_ros[dds]'" in message
    assert "\n" not in message


def test_options_are_checked(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.delenv("CYCLONEDDS_URI", raising=False)  # --dds-config sets it: restored after
    base = ["live", "--gt", GT_TOPIC, "--method", "a=/a/disparity", "--out", str(tmp_path / "o")]
    assert main([*base, "--transport", "ros"]) == 2
    err = capsys.readouterr().err
    assert "--transport dds" in err
    assert err.count("\n") == 1
    assert main([*base, "--domain-id", "300"]) == 2
    assert "out of range" in capsys.readouterr().err
    monkeypatch.setenv("ROS_DOMAIN_ID", "seven")
    assert main([*base]) == 2
    assert "ROS_DOMAIN_ID" in capsys.readouterr().err
    monkeypatch.delenv("ROS_DOMAIN_ID")
    assert main([*base, "--dds-config", str(tmp_path / "missing.xml")]) == 2
    assert "no such file" in capsys.readouterr().err
    assert main(["play", str(tmp_path / "nobag"), "--dds-config", "localhost"]) == 2
    assert "not found" in capsys.readouterr().err


# -- the raw-CDR transport -------------------------------------------------------------------


@pytest.fixture
def transports(localhost: Path) -> Iterator[tuple[Any, Any]]:
    """Two participants on a fresh domain (same process)."""
    from dispeval_ros.dds.transport import DdsTransport

    domain = fresh_domain()
    first, second = DdsTransport(domain), DdsTransport(domain)
    try:
        yield first, second
    finally:
        first.close()
        second.close()


@needs_dds
def test_disparity_image_round_trip_is_byte_identical(transports: tuple[Any, Any]) -> None:
    publisher, subscriber = transports
    store = publisher.typestore
    rng = np.random.default_rng(5)
    msg = disparity_to_msg(
        store,
        rng.random((375, 1242), dtype=np.float32) * 90,
        1_700_000_000_000_000_005,
        "left",
        721.5,
        0.54,
        0.0,
        96.0,
    )
    odd = image_to_msg(store, np.arange(9, dtype=np.uint8).reshape(3, 3), 42, "l", "mono8")
    expected = bytes(store.serialize_cdr(msg, DISPARITY))
    expected_odd = bytes(store.serialize_cdr(odd, "sensor_msgs/msg/Image"))
    assert expected[:4] == wire.CDR_LE_HEADER
    assert len(expected_odd) % 4 != 0  # exercises the padding ROS 2 nodes add

    writer = publisher.writer("/stereo/sgbm/disparity", DISPARITY, wire.PLAYBACK)
    image_writer = publisher.writer("/camera/mono", "sensor_msgs/msg/Image", wire.PLAYBACK)
    reader = subscriber.reader("/stereo/sgbm/disparity", DISPARITY, wire.SENSOR_DATA)
    image_reader = subscriber.reader("/camera/mono", "sensor_msgs/msg/Image", wire.SENSOR_DATA)
    assert wait_until(lambda: writer.matched() and reader.matched() and image_reader.matched(), 10)
    writer.publish(msg)
    writer.write_cdr(store.serialize_cdr(msg, DISPARITY, little_endian=False))  # as a BE node
    image_writer.publish(odd)

    taken: list[tuple[bytes, Any]] = []
    assert wait_until(lambda: bool(taken.extend(reader.take())) or len(taken) >= 2, 10)
    (payload, info), (swapped, _) = taken
    assert payload == expected  # byte for byte what rosbags (and a ROS 2 node) serialises
    assert info.valid_data
    decoded = reader.decode(payload)
    assert np.array_equal(decoded.image.data, msg.image.data)
    assert (decoded.f, decoded.t) == (np.float32(msg.f), np.float32(msg.t))  # float32 fields
    assert decoded.header.stamp == msg.header.stamp
    assert np.array_equal(reader.decode(swapped).image.data, msg.image.data)

    odd_taken: list[tuple[bytes, Any]] = []
    assert wait_until(lambda: bool(odd_taken.extend(image_reader.take())) or bool(odd_taken), 10)
    odd_payload = odd_taken[0][0]
    assert odd_payload == expected_odd + b"\x00" * (-len(expected_odd) % 4)
    assert np.array_equal(image_reader.decode(odd_payload).data, odd.data)

    with pytest.raises(Exception, match="not plain CDR"):
        writer.write_cdr(b"\x00\x07\x00\x00abcd")  # XCDR2 is not what ROS 2 nodes speak


@needs_dds
def test_endpoints_announce_ros2_names_qos_and_type_hash(transports: tuple[Any, Any]) -> None:
    from cyclonedds.builtin import (
        BuiltinDataReader,
        BuiltinTopicDcpsPublication,
        BuiltinTopicDcpsSubscription,
    )
    from cyclonedds.qos import Policy

    node, observer = transports
    store = node.typestore
    node.writer("/stereo/sgbm/disparity", DISPARITY, wire.RESULTS)
    node.writer(wire.GROUPS_TOPIC, wire.DIAGNOSTIC_ARRAY, wire.LATCHED)
    node.reader("/stereo/ground_truth/disparity", "sensor_msgs/msg/Image", wire.SENSOR_DATA)
    publications = BuiltinDataReader(observer.participant, BuiltinTopicDcpsPublication)
    subscriptions = BuiltinDataReader(observer.participant, BuiltinTopicDcpsSubscription)
    seen: dict[str, Any] = {}

    def discovered() -> bool:
        for sample in [*publications.take(N=100), *subscriptions.take(N=100)]:
            seen[sample.topic_name] = sample
        return {
            "rt/stereo/sgbm/disparity",
            "rt/dispeval/groups",
            "rt/stereo/ground_truth/disparity",
        } <= set(seen)

    assert wait_until(discovered, 10)
    disparity = seen["rt/stereo/sgbm/disparity"]
    assert disparity.type_name == "stereo_msgs::msg::dds_::DisparityImage_"
    assert disparity.qos[Policy.Userdata].data == wire.user_data(store, DISPARITY)
    assert disparity.qos[Policy.Reliability] == Policy.Reliability.Reliable(
        max_blocking_time=1_000_000_000
    )
    representation = disparity.qos[Policy.DataRepresentation]
    assert representation.use_cdrv0_representation
    assert not representation.use_xcdrv2_representation
    groups = seen["rt/dispeval/groups"]
    assert groups.type_name == "diagnostic_msgs::msg::dds_::DiagnosticArray_"
    assert groups.qos[Policy.Durability] == Policy.Durability.TransientLocal
    image = seen["rt/stereo/ground_truth/disparity"]
    assert image.type_name == "sensor_msgs::msg::dds_::Image_"
    assert image.qos[Policy.Reliability] == Policy.Reliability.BestEffort
    assert image.qos[Policy.Userdata].data == f"typehash={IMAGE_HASH};".encode()
    for entity in (publications, subscriptions):
        entity.__del__()


# -- the player and the session in this process ------------------------------------------


def _collect(transport: Any, player: Any) -> dict[str, list[bytes]]:
    """Readers (reliable, keep-all) for every topic a player publishes; payloads by topic."""
    got: dict[str, list[bytes]] = {}
    thread = transport.reader_thread("collect")
    for topic, played in player.topics.items():
        reader = transport.reader(topic, played.msgtype, wire.SUMMARIZER_INPUT, played.typestore)
        thread.add(reader, lambda r: got.setdefault(r.topic, []).append(r.payload), decode=False)
    thread.start()
    return got


@needs_dds
def test_player_sends_the_recorded_bytes_from_every_bag_format(
    transports: tuple[Any, Any], tmp_path: Path
) -> None:
    from rosbags.highlevel import AnyReader

    from dispeval_ros.dds.player import BagPlayer
    from dispeval_ros.offline.make_bag import synthetic_frames, write_bag

    publisher, subscriber = transports
    frames = list(synthetic_frames(3, 64, 48, 10.0, seed=4))
    bags = {
        "rosbag2-mcap": tmp_path / "r2",
        "mcap": tmp_path / "plain.mcap",
        "rosbag2-sqlite3": tmp_path / "sq",
    }
    for storage, path in bags.items():
        write_bag(path, iter(frames), storage=storage)
    bags["ros1"] = tmp_path / "drive.bag"
    as_ros1(bags.pop("rosbag2-sqlite3"), bags["ros1"])
    expected: dict[str, list[bytes]] = {}
    with AnyReader([bags["rosbag2-mcap"]]) as reader:
        for connection, _, raw in reader.messages():
            expected.setdefault(connection.topic, []).append(bytes(wire.pad_cdr(raw)))

    for storage, path in bags.items():
        player = BagPlayer(publisher, path)
        assert player.raw == (storage == "rosbag2-mcap")
        got = _collect(subscriber, player)
        assert player.wait_matched(10) == []
        assert player.play(rate=None) == sum(len(v) for v in expected.values())
        count = player.published
        assert wait_until(lambda got=got, count=count: sum(map(len, got.values())) == count, 10)
        assert got == expected, storage  # ROS 1 / plain MCAP: converted to the same bytes
        player.finish()


@needs_dds
def test_a_looping_stream_makes_new_sequences(
    transports: tuple[Any, Any], sample: Path, methods: dict[str, str], tmp_path: Path
) -> None:
    from dispeval_ros.dds.evaluator import warm_up
    from dispeval_ros.dds.player import BagPlayer
    from dispeval_ros.dds.session import LiveSession
    from dispeval_ros.stream.core import CoreConfig
    from dispeval_ros.stream.summarizer import SummarizerConfig

    publisher, _ = transports
    name, topic = next(iter(methods.items()))
    config = CoreConfig(
        methods={name: topic},
        gt_topic=GT_TOPIC,
        left_info_topic=LEFT_INFO,
        right_info_topic=RIGHT_INFO,
    )
    warm_up(config)
    summary = SummarizerConfig(tmp_path / "out", every_n=10)
    session = LiveSession(publisher.domain, config, summary, {"t": 1}, queue_size=64)
    try:
        session.start()
        player = BagPlayer(publisher, sample, list(config.topics))
        assert player.wait_matched(10) == []
        per_pass = sum(t.count for t in player.topics.values())
        stop = threading.Event()

        def two_passes(topic: str, log_ns: int) -> None:
            if player.published >= 2 * per_pass:
                stop.set()

        player.play(rate=4.0, loop=True, stop=stop, on_message=two_passes)
        assert player.published == 2 * per_pass
        assert wait_until(lambda: session.status().frames >= 50, 20), session.status()
    finally:
        session.stop()
    assert session.evaluator.restarts == 1
    with ResultsStore.open(tmp_path / "out") as store:
        assert store.sequences() == ["sequence_000", "sequence_001"]
        first, second = (store.stamps(s) for s in store.sequences())
        assert first == second
        assert len(first) == 25
        # the evaluator's counts are booked per sequence (from its delivery records), and
        # over the sequences they add up to its final counts
        booked = [store.match_counts(s)[name] for s in store.sequences()]
        assert [c.matched for c in booked] == [25, 25]
        final = session.counts[name]
        for field in ("matched", "unmatched", "dropped", "failed"):
            assert sum(getattr(c, field) for c in booked) == getattr(final, field), field
        assert store.problems() == []


@needs_dds
def test_summarizer_books_the_evaluator_counts_per_sequence(
    transports: tuple[Any, Any], tmp_path: Path
) -> None:
    """Counts from delivery records go to the sequence they happened in; arrays that never
    arrived are counted as dropped, with a problem saying so."""
    from dispeval_ros.core import Evaluator
    from dispeval_ros.dds.summarizer import DdsSummarizer
    from dispeval_ros.stream.core import MethodCounts
    from dispeval_ros.stream.delivery import Delivery
    from dispeval_ros.stream.summarizer import SummarizerConfig

    gt = np.full((6, 8), 10.0, np.float32)
    frame = {"m": Evaluator(("all",)).score(gt, gt + 0.5)}
    summarizer = DdsSummarizer(
        transports[0], SummarizerConfig(tmp_path / "out", every_n=2), {"t": 1}
    )

    def delivery(index: int, matched: int, unmatched: int, dropped: int = 0) -> list[Delivery]:
        counts = {"m": MethodCounts(matched, unmatched, dropped, 0)}
        return [Delivery("evaluator", index, final=False, counts=counts)]

    second = 1_000_000_000
    # sequence 1: two frames, the evaluator could not match 2 estimates so far
    summarizer.add(1 * second, frame, [], delivery(1, 1, 1))
    summarizer.add(2 * second, frame, [("m", "late estimate")], delivery(2, 2, 2))
    # the stream starts again (a stamp seen before): sequence 2; array 4 never arrives
    summarizer.add(1 * second, frame, [], delivery(3, 3, 3))
    final = Delivery("evaluator", 4, final=True, counts={"m": MethodCounts(4, 5, 1, 0)})
    summarizer.finish(final)
    with ResultsStore.open(tmp_path / "out") as store:
        first, last = store.sequences()
        assert store.match_counts(first)["m"] == MatchCounts(2, 2, 0, 0)
        # 5 - 2 unmatched; dropped: 1 by the evaluator + the 1 scored frame that never came
        assert store.match_counts(last)["m"] == MatchCounts(1, 3, 2, 0)
        problems = store.problems()
        assert [(p.sequence, p.stamp, p.method) for p in problems[:1]] == [(first, 2 * second, "m")]
        assert any("never reached the summarizer" in p.message for p in problems[1:])


# -- dispeval live + dispeval play, separate processes ---------------------------------------


GT_MODES = {
    "image": ["--gt", GT_TOPIC, "--camera-info", LEFT_INFO, RIGHT_INFO],
    "cloud": ["--gt-cloud", CLOUD_TOPIC, "--camera-info", LEFT_INFO, RIGHT_INFO],
    "images": ["--gt", GT_TOPIC, "--left-image", LEFT_IMAGE, "--right-image", RIGHT_IMAGE],
    "no-gt": ["--left-image", LEFT_IMAGE, "--right-image", RIGHT_IMAGE],
}
"""Ground truth as an image, or from the LiDAR with the extrinsic from /tf_static; with the
rectified images too (ground-truth-free measures), or the images alone."""
GT_MODE_TOPICS = {
    "image": [GT_TOPIC, LEFT_INFO, RIGHT_INFO],
    "cloud": [CLOUD_TOPIC, TF_STATIC_TOPIC, LEFT_INFO, RIGHT_INFO],
    "images": [GT_TOPIC, LEFT_IMAGE, RIGHT_IMAGE],
    "no-gt": [LEFT_IMAGE, RIGHT_IMAGE],
}


@pytest.fixture(scope="module")
def references(
    sample: Path, methods: dict[str, str], tmp_path_factory: pytest.TempPathFactory
) -> Callable[[str], dict[tuple[int, str], Any]]:
    """What ``dispeval bag`` stores for the sample bag: (GT stamp, method) → Scores."""
    cache: dict[str, dict[tuple[int, str], Any]] = {}

    def reference(mode: str) -> dict[tuple[int, str], Any]:
        if mode not in cache:
            out = tmp_path_factory.mktemp("bag") / "out"
            args = ["bag", str(sample), *GT_MODES[mode]]
            for name, topic in methods.items():
                args += ["--method", f"{name}={topic}"]
            assert main([*args, "--out", str(out), "--quiet"]) == 0
            with ResultsStore.open(out) as store:
                (sequence,) = store.sequences()
                assert store.problems() == []
                cache[mode] = {
                    (stamp, method): scores
                    for stamp in store.stamps(sequence)
                    for method, scores in store.frame_scores(sequence, stamp).items()
                }
        return cache[mode]

    return reference


def _assert_same_scores(rebuilt: Any, expected: Any, where: Any) -> None:
    np.testing.assert_array_equal(rebuilt.sums, expected.sums, err_msg=str(where))
    for criterion in expected.criteria:
        for measure, value in expected[criterion].items():
            got = rebuilt[criterion][measure]
            assert got == value or (math.isnan(got) and math.isnan(value)), (where, measure)


def _waits_for_calibration(problem: str) -> bool:
    """Whether a frame's problem is that no CameraInfo pair had arrived for it (either wording)."""
    return "no camera yet" in problem or "no CameraInfo pair received yet" in problem


@needs_dds
@pytest.mark.parametrize("gt_mode", sorted(GT_MODES))
def test_live_and_play_over_dds_match_dispeval_bag(
    sample: Path,
    methods: dict[str, str],
    references: Callable[[str], dict[tuple[int, str], Any]],
    localhost: Path,
    tmp_path: Path,
    gt_mode: str,
) -> None:
    from dispeval_ros.dds.transport import DdsTransport

    reference = references(gt_mode)
    domain = fresh_domain()
    gt_stamps = sorted({stamp for stamp, _ in reference})
    topics = [*GT_MODE_TOPICS[gt_mode], *methods.values()]
    with BagSource(sample) as source:
        published = sum(source.topics[topic].count for topic in topics)
    dds = ["--domain-id", str(domain), "--dds-config", "localhost"]
    out = tmp_path / "live"
    scores: list[tuple[int, list[StatusRecord]]] = []
    groups: list[tuple[int, list[StatusRecord]]] = []
    lock = threading.Lock()

    def keep(into: list[Any]) -> Callable[[Any], None]:
        def handler(received: Any) -> None:
            with lock:
                into.append(records_of(received.msg))

        return handler

    transport = DdsTransport(domain)
    live = play = None
    try:
        scores_reader = transport.reader(
            wire.SCORES_TOPIC, wire.DIAGNOSTIC_ARRAY, wire.SUMMARIZER_INPUT
        )
        groups_reader = transport.reader(wire.GROUPS_TOPIC, wire.DIAGNOSTIC_ARRAY, wire.LATCHED)
        listener = transport.reader_thread("test")
        listener.add(scores_reader, keep(scores))
        listener.add(groups_reader, keep(groups))
        listener.start()

        method_args = [
            a for name, topic in methods.items() for a in ("--method", f"{name}={topic}")
        ]
        live_log = tmp_path / "live.log"
        live = dispeval_process(
            "live",
            *GT_MODES[gt_mode],
            *method_args,
            "--out",
            str(out),
            "--summary-every",
            "5",
            "--queue-size",
            "64",
            "--quiet",
            *dds,
            log=live_log,
        )
        ready = wait_until(lambda: "listening on" in live_log.read_text(errors="replace"), 90)
        assert ready, live_log.read_text(errors="replace")
        assert wait_until(lambda: scores_reader.matched() > 0, 30), "live's scores not discovered"

        play_log = tmp_path / "play.log"
        play = dispeval_process(
            "play",
            str(sample),
            "--topics",
            *topics,
            "--wait-matched",
            "30",
            "--quiet",
            *dds,
            log=play_log,
        )
        assert play.wait(timeout=90) == 0, play_log.read_text(errors="replace")
        assert f"published {published} messages" in play_log.read_text()

        def settled() -> bool:
            with lock:
                count = len(scores)
            time.sleep(1.0)
            with lock:
                return len(scores) == count and (count == len(gt_stamps) or count > 0)

        wait_until(settled, 30, step=0.0)
        live.send_signal(signal.SIGINT)
        assert live.wait(timeout=90) == 0, live_log.read_text(errors="replace")
        wait_until(lambda: bool(groups) and len(groups[-1][1]) == len(methods), 5)
    finally:
        for process in (live, play):
            if process is not None and process.poll() is None:
                process.kill()
                process.wait()
        transport.close()

    text = live_log.read_text(errors="replace")
    # every frame received here equals dispeval bag's, exactly
    received: dict[int, set[str]] = {}
    # LiDAR GT cannot be projected before the first CameraInfo pair: over best-effort DDS the
    # very first samples may be lost while discovery completes, so the first frames may fail
    # (each with one clear problem); the image GT falls back to the DisparityImage's f and t.
    waiting = set(gt_stamps[:3]) if gt_mode == "cloud" else set()
    startup: set[int] = set()
    # every scores array carries one delivery record of the one evaluator, numbered 1, 2, …
    deliveries = [[d for d in map(read_delivery, records) if d] for _, records in scores]
    assert all(len(found) == 1 for found in deliveries)
    assert len({found[0].source for found in deliveries}) == 1
    assert [found[0].index for found in deliveries] == list(range(1, len(scores) + 1))
    scores = [(stamp, [r for r in records if not read_delivery(r)]) for stamp, records in scores]
    for stamp, records in scores:
        assert stamp in gt_stamps
        if stamp in waiting and any(_waits_for_calibration(r.message) for r in records):
            startup.add(stamp)
            continue
        for record in records:
            assert record.values, f"a problem was reported: {record.message}"
            rebuilt = scores_from_status(record.values)
            _assert_same_scores(rebuilt, reference[stamp, record.name], (stamp, record.name))
            received.setdefault(stamp, set()).add(record.name)
    assert len(scores) == len(received) + len(startup), "a frame was published twice"
    assert len(received) >= len(gt_stamps) - 3, f"only {len(received)} of {len(gt_stamps)} frames"

    # the live process's database holds exactly the frames it published, the same scores
    with ResultsStore.open(out) as store:
        (sequence,) = store.sequences()
        assert store.stamps(sequence) == sorted(received)
        for stamp, names in received.items():
            stored = store.frame_scores(sequence, stamp)
            assert set(stored) == names
            for method, stored_scores in stored.items():
                _assert_same_scores(stored_scores, reference[stamp, method], (stamp, method))
        counts = store.match_counts(sequence)
        assert set(counts) == set(methods)
        for method, count in counts.items():
            assert count.matched == sum(method in names for names in received.values())
            assert count.failed <= len(startup)
            assert count.matched + count.dropped <= len(gt_stamps)
            assert count.unmatched <= len(gt_stamps) - count.matched
        assert {problem.stamp for problem in store.problems()} == startup
    summary = json.loads((out / "summary.json").read_text())
    assert summary["sequences"][0]["common_frames"] == sum(
        len(names) == len(methods) for names in received.values()
    )
    assert (out / "frames.csv").read_text().startswith("sequence,stamp,method")
    assert "=== sequence sequence_000" in text

    # the groups came out, the last one covering every method
    assert groups, "no groups received"
    final = {record.name: dict(record.values) for record in groups[-1][1]}
    assert set(final) == set(methods)
    assert all(values["group"].isdigit() for values in final.values())
    assert {values["interpretation"] for values in final.values()} == {
        summary["sequences"][0]["models"]["interpretation"]
    }


@needs_dds
def test_estimates_that_cannot_be_scored_are_failed_and_keep_their_arrivals(
    localhost: Path, tmp_path: Path
) -> None:
    """Over DDS as over rclpy: an estimate delivered but not scored (wrong size, an encoding
    that cannot be read) is failed for its method, in the shutdown counts, the database,
    ``summary.json`` and the summary; its arrival is kept (``timing.json``), on a frame where
    one method fails, where both do, and where the ground truth cannot be read."""
    from dispeval_ros.dds.session import LiveSession
    from dispeval_ros.dds.transport import DdsTransport
    from dispeval_ros.stream.core import CoreConfig
    from dispeval_ros.stream.summarizer import SummarizerConfig
    from dispeval_ros.stream.vectors import arrivals_of

    domain = fresh_domain()
    topics = {"good": "/test/good/disparity", "bad": "/test/bad/disparity"}
    config = CoreConfig(methods=topics, gt_topic="/test/gt")
    out = tmp_path / "live"
    errors: list[str] = []
    summary_config = SummarizerConfig(out, every_n=1)
    session = LiveSession(domain, config, summary_config, {"t": 1}, on_error=errors.append)
    feed = DdsTransport(domain)
    scores: list[tuple[int, list[StatusRecord]]] = []
    try:
        store = feed.typestore
        writers = {
            name: feed.writer(topic, DISPARITY, wire.PLAYBACK) for name, topic in topics.items()
        }
        gt_writer = feed.writer(config.gt_topic, "sensor_msgs/msg/Image", wire.PLAYBACK)
        listener = feed.reader(wire.SCORES_TOPIC, wire.DIAGNOSTIC_ARRAY, wire.SUMMARIZER_INPUT)
        thread = feed.reader_thread("test")
        thread.add(listener, lambda received: scores.append(records_of(received.msg)))
        thread.start()
        session.start()
        everything = [gt_writer, *writers.values()]
        assert wait_until(lambda: all(w.matched() for w in everything) and listener.matched(), 10)

        def disparity(array: np.ndarray, stamp: int, encoding: str = "32FC1") -> Any:
            msg = disparity_to_msg(store, array, stamp, "left", 100.0, 0.5, 0.0, 64.0)
            if encoding != "32FC1":
                msg.image.encoding = encoding
            return msg

        rows, columns = np.mgrid[0:24, 0:32]
        previous = 0
        for k, case in enumerate(["bad size", "both fail", "both scored", "gt fails", "bad enc"]):
            stamp = max(time.time_ns(), previous + 1)  # stamped as sent: never after its receipt
            previous = stamp
            gt = (8.0 + 0.25 * columns + 0.1 * rows + k).astype(np.float32)
            good, bad = gt + np.float32(0.3), gt + np.float32(2.0)
            gt_msg = image_to_msg(store, gt, stamp, "left", "32FC1")
            if case == "gt fails":
                gt_msg = image_to_msg(store, np.zeros((24, 32, 3), np.uint8), stamp, "left", "rgb8")
            gt_writer.publish(gt_msg)
            writers["good"].publish(disparity(good[:12] if case == "both fail" else good, stamp))
            if case in ("bad size", "both fail"):
                writers["bad"].publish(disparity(bad[:12], stamp))
            elif case == "bad enc":
                writers["bad"].publish(disparity(bad.view(np.uint8)[:, :32], stamp, "rgb8"))
            else:
                writers["bad"].publish(disparity(bad, stamp))
            assert wait_until(lambda k=k: len(scores) == k + 1, 30), (case, len(scores))
    finally:
        session.stop()
        feed.close()

    assert errors == []  # each problem is the frame's, not a transport error
    stamps = [stamp for stamp, _ in scores]
    assert stamps == sorted(stamps)
    assert len(stamps) == 5
    published: dict[tuple[int, str], tuple[int, int]] = {}
    for _, records in scores:
        for record in records:
            if read_delivery(record) is None:
                published.update(((t[0], m), t) for m, t in arrivals_of(record).items())
    assert published.keys() == {(s, m) for s in stamps for m in topics}  # every arrival
    assert all(arrival >= sent for sent, arrival in published.values())
    failed = {"good": 2, "bad": 4}  # 'good': both fail, gt fails; 'bad': all but 'both scored'
    assert {m: c.failed for m, c in session.counts.items()} == failed
    assert {m: c.matched for m, c in session.counts.items()} == {"good": 3, "bad": 1}
    with ResultsStore.open(out) as results:
        (sequence,) = results.sequences()
        stored = {
            (entry.estimate_stamp, method): (entry.estimate_stamp, entry.arrival)
            for method, entries in (results.timing(sequence) or {}).items()
            for entry in entries
        }
        assert stored == published
        counts = results.match_counts(sequence)
        assert {m: c.failed for m, c in counts.items()} == failed
        assert results.stamps(sequence) == [stamps[0], stamps[2], stamps[4]]
        assert sorted((p.stamp, p.method or "") for p in results.problems()) == [
            (stamps[0], "bad"),
            (stamps[1], "bad"),
            (stamps[1], "good"),
            (stamps[3], ""),
            (stamps[4], "bad"),
        ]
    summary = json.loads((out / "summary.json").read_text())
    assert {m: c["failed"] for m, c in summary["sequences"][0]["counts"].items()} == failed
    timing = json.loads((out / "timing.json").read_text())
    assert {name.rpartition("/")[2] for name in timing} == set(topics)


def odometry_of(typestore: Any, frame: Any) -> Any:
    """make-bag's odom → base_link of a frame as a nav_msgs/Odometry (the rig never turns)."""
    types = typestore.types
    stamp = START_NS + round(frame.stamp * 1e9)
    assert np.array_equal(frame.odometry[:3, :3], np.eye(3))
    x, y, z = (float(v) for v in frame.odometry[:3, 3])
    pose = types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=x, y=y, z=z),
        orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    twist = types["geometry_msgs/msg/Twist"](
        linear=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
        angular=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
    )
    return types["nav_msgs/msg/Odometry"](
        header=diagnostics_header(typestore, stamp, "odom"),
        child_frame_id="base_link",
        pose=types["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
        twist=types["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)),
    )


@needs_dds
@pytest.mark.parametrize("motion", ["tf", "odometry"])
def test_live_egomotion_over_dds_matches_dispeval_bag(
    transports: tuple[Any, Any], tmp_path: Path, motion: str
) -> None:
    """``live --egomotion``: make-bag's drive (its exact motion on /tf, the camera's mount on
    /tf_static, latched) played over DDS gives each method's ego-motion residual exactly as
    ``dispeval bag --egomotion`` scores it from the same bag, pairs and pooled sums; so does
    the drive with its motion sent as nav_msgs/Odometry and the mount given (``--odometry``,
    ``--camera-mount``) instead of /tf and /tf_static."""
    from dispeval_ros.cli.live_cmd import live_record
    from dispeval_ros.dds.evaluator import subscription_qos, warm_up
    from dispeval_ros.dds.player import BagPlayer
    from dispeval_ros.dds.session import LiveSession
    from dispeval_ros.offline.make_bag import synthetic_frames, write_bag
    from dispeval_ros.stream.core import CoreConfig
    from dispeval_ros.stream.summarizer import SummarizerConfig
    from dispeval_ros.testbed.methods import default_methods

    frames = list(synthetic_frames(5, 320, 96, 10.0, seed=4))
    bag = tmp_path / "drive"
    write_bag(bag, iter(frames), storage="rosbag2-sqlite3", methods=default_methods(320)[:1])
    with BagSource(bag) as source:
        (method,) = [t for t, i in source.topics.items() if i.msgtype == DISPARITY]
    name = method.split("/")[2]
    config = CoreConfig(
        methods={name: method},
        gt_topic=GT_TOPIC,
        left_info_topic=LEFT_INFO,
        right_info_topic=RIGHT_INFO,
        left_image_topic=LEFT_IMAGE,
        right_image_topic=RIGHT_IMAGE,
        egomotion=True,
    )
    tf_type = "tf2_msgs/msg/TFMessage"
    assert subscription_qos("/tf", tf_type, wire.SENSOR_DATA) == wire.DYNAMIC_TF
    assert subscription_qos(TF_STATIC_TOPIC, tf_type, wire.SENSOR_DATA) == wire.STATIC_TF
    reference = tmp_path / "bag"
    argv = ["bag", str(bag), "--gt", GT_TOPIC, "--method", f"{name}={method}", "--camera-info"]
    argv += [LEFT_INFO, RIGHT_INFO, "--left-image", LEFT_IMAGE, "--right-image", RIGHT_IMAGE]
    assert main([*argv, "--egomotion", "--out", str(reference), "--quiet"]) == 0
    with ResultsStore.open(reference) as store:
        (sequence,) = store.sequences()
        expected = store.motion_pairs(sequence)
    assert expected is not None
    assert expected[name][0] == len(frames) - 1

    publisher, _ = transports
    warm_up(config)
    out = tmp_path / "live"
    record = live_record(config)
    odometry = "/robot/odom" if motion == "odometry" else None
    mount = frames[0].camera_mount if odometry else None
    session = LiveSession(
        publisher.domain, config, SummarizerConfig(out), record, queue_size=64,
        odometry=odometry, mount=mount,
    )  # fmt: skip
    topics = list(config.topics)
    try:
        session.start()
        calibration = BagPlayer(publisher, bag, [LEFT_INFO, RIGHT_INFO])
        assert calibration.wait_matched(10) == []
        calibration.play(rate=None)  # the camera first: every frame then has its principal point
        assert wait_until(lambda: session.evaluator.live.core.camera() is not None, 30)
        if odometry is not None:  # the motion first, as Odometry; no /tf, no /tf_static
            topics = [t for t in topics if t not in ("/tf", TF_STATIC_TOPIC)]
            assert sorted(r.topic for r in session.evaluator.readers) == sorted([*topics, odometry])
            writer = publisher.writer(odometry, "nav_msgs/msg/Odometry", wire.PLAYBACK)
            assert wait_until(lambda: writer.matched() > 0, 10)
            for frame in frames:
                writer.publish(odometry_of(publisher.typestore, frame))
            source = session.evaluator.live.core.motion
            last = START_NS + round(frames[-1].stamp * 1e9)
            assert wait_until(lambda: source.ready(last, "stereo_left"), 10), source.problems()
        player = BagPlayer(publisher, bag, topics)
        assert player.wait_matched(10) == []
        player.play(rate=1.0)
        assert wait_until(lambda: session.status().frames >= len(frames), 30), session.status()
    finally:
        session.stop()
    with ResultsStore.open(out) as store:
        (sequence,) = store.sequences()
        got = store.motion_pairs(sequence)
        assert store.problems() == []
    assert got is not None
    assert got[name][0] == expected[name][0]
    np.testing.assert_array_equal(got[name][1].sums, expected[name][1].sums)
