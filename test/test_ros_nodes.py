"""The rclpy nodes in-process: real publishers, subscriptions and services (needs ROS 2).

Messages are built with rclpy's generated classes (helpers mirroring the rosbags encoders of
``dispeval_ros.io.messages``) and published to the evaluator, whose ``/dispeval/scores`` must
equal what :class:`~dispeval_ros.stream.core.EvaluationCore` computes on the very same message
objects, to the last bit. Skipped where rclpy is not installed (outside a ROS 2 environment);
``colcon test`` runs it.
"""

from __future__ import annotations

import importlib
import json
import os
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ros_support import Ros, input_types, ros_import
from rosbags.typesys import Stores, get_typestore
from sample_feed import (
    Stream,
    bag_reference,
    expected_counts,
    robot_stream,
    sample_bag,
    sample_config,
)

from dispeval_ros.core import Camera, Evaluator
from dispeval_ros.core.measures import SEQUENCE_MEASURES
from dispeval_ros.io.messages import image_from_msg, stamp_ns
from dispeval_ros.io.store import MatchCounts, ResultsStore
from dispeval_ros.ros.params import (
    DOUBLE,
    EVALUATOR_PARAMETERS,
    INTEGER,
    SUMMARIZER_PARAMETERS,
    Param,
)
from dispeval_ros.stream.core import EvaluationCore, FrameResult, MethodCounts
from dispeval_ros.stream.delivery import DELIVERY_STATUS, delivery_record, read_delivery
from dispeval_ros.stream.images import colour_error
from dispeval_ros.stream.vectors import (
    ERROR,
    OK,
    PROBLEM_KEY,
    AlarmThresholds,
    problem_status,
    score_vector,
    scores_from_status,
    scores_status,
    vector_labels,
)

rclpy = ros_import("rclpy")
rclpy_context = ros_import("rclpy.context")
rclpy_executors = ros_import("rclpy.executors")
rclpy_parameter = ros_import("rclpy.parameter")
diagnostic_msgs = ros_import("diagnostic_msgs.msg")
rcl_interfaces = ros_import("rcl_interfaces.msg")
sensor_msgs = ros_import("sensor_msgs.msg")
std_msgs = ros_import("std_msgs.msg")
std_srvs = ros_import("std_srvs.srv")
stereo_msgs = ros_import("stereo_msgs.msg")

# Imported only now: they need rclpy (import errors in them must fail, not skip).
convert = importlib.import_module("dispeval_ros.ros.convert")
evaluator_node = importlib.import_module("dispeval_ros.ros.evaluator")
summarizer_node = importlib.import_module("dispeval_ros.ros.summarizer")

Parameter = rclpy_parameter.Parameter

DOMAIN_ID = 50 + os.getpid() % 50
"""A domain of its own, so that other ROS 2 processes on the machine do not interfere."""
TIMEOUT = 60.0
H, W = 48, 64
F, BASELINE = 100.0, 0.125
"""Exact in float32, so the DisparityImage's f and t give the CameraInfo pair's camera."""
FRAME_NS = 100_000_000
START_NS = 1_700_000_000_000_000_000


# -- harness ------------------------------------------------------------------------------------


@pytest.fixture
def ros() -> Iterator[Ros]:
    harness = Ros(DOMAIN_ID, evaluator_node.EvaluatorNode, summarizer_node.SummarizerNode)
    try:
        yield harness
    finally:
        harness.close()


class Topics:
    """Input topics of one test (unique, so tests never see each other's messages)."""

    def __init__(self, name: str) -> None:
        base = f"/dispeval_test_{name}_{os.getpid()}"
        self.gt = f"{base}/ground_truth"
        self.left = f"{base}/left/camera_info"
        self.right = f"{base}/right/camera_info"
        self.good = f"{base}/good/disparity"
        self.bad = f"{base}/bad/disparity"


# -- messages built with the rclpy classes ---------------------------------------------------------


def gt_map(k: int) -> np.ndarray:
    """A slanted plane with a band of missing ground truth; a bit different every frame."""
    columns = np.arange(W, dtype=np.float32)
    gt = np.broadcast_to(8.0 + 0.25 * columns + k, (H, W)).astype(np.float32)
    gt[:, :6] = 0.0
    gt[H // 2 :, W // 2 : W // 2 + 8] += 10.0  # a nearer box: boundaries and occlusions
    return gt


def estimate(gt: np.ndarray, error: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    est = gt + rng.normal(0.0, error, gt.shape).astype(np.float32)
    est[:4, :] = -1.0  # stereo_image_proc's invalid marker (min_disparity - 1): missing
    return est.astype(np.float32)


def image_msg(array: np.ndarray, stamp: int, encoding: str = "32FC1") -> Any:
    return convert.image_msg(array, stamp, "stereo_left", encoding)


def disparity_msg(disparity: np.ndarray, stamp: int) -> Any:
    height, width = disparity.shape
    return stereo_msgs.DisparityImage(
        header=convert.header_msg(stamp, "stereo_left"),
        image=image_msg(disparity, stamp),
        f=F,
        t=BASELINE,
        valid_window=sensor_msgs.RegionOfInterest(
            x_offset=0, y_offset=0, height=height, width=width, do_rectify=False
        ),
        min_disparity=0.0,
        max_disparity=64.0,
        delta_d=1.0 / 16.0,
    )


def camera_info_msg(stamp: int, right: bool) -> Any:
    cx, cy = W / 2.0 - 0.5, H / 2.0 - 0.5
    tx = -F * BASELINE if right else 0.0
    return sensor_msgs.CameraInfo(
        header=convert.header_msg(stamp, "stereo_right" if right else "stereo_left"),
        height=H,
        width=W,
        distortion_model="plumb_bob",
        d=[0.0] * 5,
        k=np.array([F, 0.0, cx, 0.0, F, cy, 0.0, 0.0, 1.0]),
        r=np.eye(3).reshape(-1),
        p=np.array([F, 0.0, cx, tx, 0.0, F, cy, 0.0, 0.0, 0.0, 1.0, 0.0]),
        binning_x=0,
        binning_y=0,
        roi=sensor_msgs.RegionOfInterest(),
    )


def frame_messages(topics: Topics, k: int, bad_shape: bool = False) -> list[tuple[str, Any]]:
    stamp = START_NS + k * FRAME_NS
    gt = gt_map(k)
    bad = estimate(gt, 2.0, 100 + k)
    if bad_shape:
        bad = bad[: H // 2]
    return [
        (topics.gt, image_msg(gt, stamp)),
        (topics.good, disparity_msg(estimate(gt, 0.3, k), stamp)),
        (topics.bad, disparity_msg(bad, stamp)),
    ]


def publishers(ros: Ros, topics: Topics) -> dict[str, Any]:
    types = {
        topics.gt: sensor_msgs.Image,
        topics.left: sensor_msgs.CameraInfo,
        topics.right: sensor_msgs.CameraInfo,
        topics.good: stereo_msgs.DisparityImage,
        topics.bad: stereo_msgs.DisparityImage,
    }
    return make_publishers(ros, types)


def make_publishers(ros: Ros, types: dict[str, Any]) -> dict[str, Any]:
    return {topic: ros.helper.create_publisher(kind, topic, 10) for topic, kind in types.items()}


def matched(pubs: dict[str, Any], topics: list[str]) -> Callable[[], bool]:
    return lambda: all(pubs[topic].get_subscription_count() > 0 for topic in topics)


def scores_once_matched(ros: Ros, node: Any, pubs: dict[str, Any], topics: list[str]) -> list[Any]:
    """The node's ``/dispeval/scores`` as they arrive, collected once ``topics``' publishers
    and the collector are matched with the node."""
    scores = ros.collect(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", evaluator_node.RESULTS_QOS
    )
    assert ros.spin_until(matched(pubs, topics))
    assert ros.spin_until(lambda: node._scores_pub.get_subscription_count() > 0)
    return scores


def statuses(array: Any) -> dict[str, Any]:
    """Method and problem statuses by name (the delivery record apart: see delivery_of)."""
    return {status.name: status for status in array.status if status.name != DELIVERY_STATUS}


def delivery_of(array: Any) -> Any:
    """The delivery record of a scores array (None if it has none)."""
    for status in array.status:
        if status.name == DELIVERY_STATUS:
            return read_delivery(convert.status_record(status))
    return None


# -- evaluator --------------------------------------------------------------------------------------


def descriptor_type(param: Param) -> int:
    types = rcl_interfaces.ParameterType
    return {
        "bool": types.PARAMETER_BOOL,
        "integer": types.PARAMETER_INTEGER,
        "double": types.PARAMETER_DOUBLE,
        "string": types.PARAMETER_STRING,
        "string[]": types.PARAMETER_STRING_ARRAY,
    }[param.kind]


def check_descriptors(node: Any, table: tuple[Param, ...]) -> None:
    for param in table:
        descriptor = node.describe_parameter(param.name)
        assert descriptor.description == param.description
        assert descriptor.additional_constraints == param.constraints
        assert descriptor.read_only == param.read_only
        assert descriptor.type == descriptor_type(param)
        if param.low is not None:
            ranges = (
                descriptor.floating_point_range
                if param.kind == DOUBLE
                else descriptor.integer_range
            )
            assert param.kind in (DOUBLE, INTEGER)
            assert len(ranges) == 1
            assert (ranges[0].from_value, ranges[0].to_value) == (param.low, param.high)


def test_parameters_have_descriptors_and_alarms_change_at_run_time(ros: Ros) -> None:
    topics = Topics("params")
    node = ros.evaluator(methods=[f"good:{topics.good}"], gt_topic=topics.gt)
    check_descriptors(node, EVALUATOR_PARAMETERS)
    assert node.get_parameter("queue_size").value == 4
    assert list(node.get_parameter("criteria").value) == ["all", "visibility", "depth"]
    assert node.config.methods == {"good": topics.good}
    assert node.config.measures is None  # [default]: the core's default for the GT kind

    (refused,) = node.set_parameters([Parameter("gt_topic", value="/elsewhere")])
    assert not refused.successful  # read-only
    (bad,) = node.set_parameters([Parameter("alarm_warn", value=["bmp"])])
    assert not bad.successful
    assert "CRITERION/MEASURE" in bad.reason
    (good,) = node.set_parameters([Parameter("alarm_warn", value=["all/bmp=0"])])
    assert good.successful


def parameter_values(ros: Ros, node_name: str) -> dict[str, Any]:
    """What ``ros2 param dump`` reads: ListParameters, then GetParameters of every name."""
    services = importlib.import_module("rcl_interfaces.srv")
    lister = ros.helper.create_client(services.ListParameters, f"/{node_name}/list_parameters")
    getter = ros.helper.create_client(services.GetParameters, f"/{node_name}/get_parameters")
    assert lister.wait_for_service(timeout_sec=TIMEOUT)
    assert getter.wait_for_service(timeout_sec=TIMEOUT)
    listed = lister.call_async(services.ListParameters.Request())
    assert ros.spin_until(listed.done)
    names = list(listed.result().result.names)
    got = getter.call_async(services.GetParameters.Request(names=names))
    assert ros.spin_until(got.done)
    values = list(got.result().values)
    assert len(values) == len(names), "GetParameters answered nothing: a parameter is unset"
    return {
        name: Parameter.from_parameter_msg(rcl_interfaces.Parameter(name=name, value=value))
        for name, value in zip(names, values, strict=True)
    }


def test_param_dump_answers_every_parameter(ros: Ros, tmp_path: Path) -> None:
    topics = Topics("dump")
    ros.evaluator(methods=[f"good:{topics.good}"], gt_topic=topics.gt)
    ros.summarizer(output_dir=str(tmp_path / "out"))
    for node_name, table in (
        ("dispeval_evaluator", EVALUATOR_PARAMETERS),
        ("dispeval_summarizer", SUMMARIZER_PARAMETERS),
    ):
        values = parameter_values(ros, node_name)
        for param in table:
            assert values[param.name].type_ != Parameter.Type.NOT_SET, param.name
    evaluator_values = parameter_values(ros, "dispeval_evaluator")
    assert list(evaluator_values["measures"].value) == ["default"]
    assert evaluator_values["alarm_warn"].type_ == Parameter.Type.STRING_ARRAY
    assert list(evaluator_values["alarm_warn"].value) == []
    assert list(evaluator_values["methods"].value) == [f"good:{topics.good}"]


def test_empty_array_defaults_are_never_read_only() -> None:
    """A typed empty value is set after declaring; ROS refuses that for read-only ones."""
    for param in (*EVALUATOR_PARAMETERS, *SUMMARIZER_PARAMETERS):
        if param.default == ():
            assert not param.read_only, param.name


def test_summarizer_parameters_have_descriptors(ros: Ros, tmp_path: Path) -> None:
    node = ros.summarizer(output_dir=str(tmp_path / "out"))
    check_descriptors(node, SUMMARIZER_PARAMETERS)
    assert node.options.config.out == tmp_path / "out"


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
            assert convert.status_values(status) == list(record.values)  # exact numbers
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
    ((key, text),) = convert.status_values(problem)
    assert key == PROBLEM_KEY
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


# -- summarizer -------------------------------------------------------------------------------------


def synthetic_scores(frames: int) -> list[tuple[int, dict[str, Any]]]:
    evaluator = Evaluator(("all", "depth"), SEQUENCE_MEASURES)
    camera = Camera(F, BASELINE)
    result = []
    for k in range(frames):
        gt = gt_map(k)
        result.append(
            (
                START_NS + k * FRAME_NS,
                {
                    "good": evaluator.score(gt, estimate(gt, 0.3, k), camera=camera),
                    "bad": evaluator.score(gt, estimate(gt, 2.0, 100 + k), camera=camera),
                },
            )
        )
    return result


def evaluator_of(ros: Ros, config: Any, **parameters: Any) -> Any:
    """An evaluator node for the topics of a core configuration (and more parameters)."""
    return ros.evaluator(
        methods=[f"{m}:{t}" for m, t in config.methods.items()],
        gt_topic=config.gt_topic,
        left_camera_info=config.left_info_topic,
        right_camera_info=config.right_info_topic,
        **parameters,
    )


def summarizer_with_publisher(ros: Ros, **parameters: Any) -> tuple[Any, Any]:
    """A summarizer node and a publisher of /dispeval/scores it has matched."""
    node = ros.summarizer(**parameters)
    publisher = ros.helper.create_publisher(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", summarizer_node.SCORES_QOS
    )
    assert ros.spin_until(lambda: publisher.get_subscription_count() > 0)
    return node, publisher


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

# The LiDAR (x forward, y left, z up) 0.3 m above the left camera, looking the same way.
LIDAR_TO_OPTICAL = np.array(
    [[0, -1, 0, 0.0], [0, 0, -1, -0.3], [1, 0, 0, 0.0], [0, 0, 0, 1]], dtype=np.float64
)


def lidar_scene(k: int) -> np.ndarray:
    """A wall 12 m ahead with a box 6 m ahead in front of it (LiDAR frame, N×3)."""
    y, z = np.meshgrid(np.linspace(-6, 6, 140), np.linspace(-2.5, 1.5, 40))
    depth = np.where((np.abs(y + 0.1 * k) < 1.0) & (z < 0), 6.0, 12.0)
    return np.column_stack([depth.ravel(), y.ravel(), z.ravel()]).astype(np.float32)


def cloud_msg(points: np.ndarray, stamp: int) -> Any:
    """An unorganised PointCloud2 with x, y, z and an intensity field (16-byte points)."""
    record = np.zeros(len(points), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("i", "<f4")])
    for column, name in enumerate("xyz"):
        record[name] = points[:, column]
    fields = [
        sensor_msgs.PointField(name=name, offset=4 * index, datatype=7, count=1)
        for index, name in enumerate(("x", "y", "z", "intensity"))
    ]
    return sensor_msgs.PointCloud2(
        header=convert.header_msg(stamp, "velodyne"),
        height=1,
        width=len(points),
        fields=fields,
        is_bigendian=False,
        point_step=16,
        row_step=16 * len(points),
        data=record.tobytes(),
        is_dense=True,
    )


def publish_frame(
    ros: Ros, pubs: dict[str, Any], core: EvaluationCore, scores: list[Any], messages: list[Any]
) -> list[FrameResult]:
    """Publish one frame's messages to the node and push them into ``core``; wait for its scores.

    Returns what the core scored for it.
    """
    before = len(scores)
    expected: list[FrameResult] = []
    for topic, msg in messages:
        pubs[topic].publish(msg)
        expected.extend(core.score(frame_set) for frame_set in core.push(topic, msg))
    assert ros.spin_until(lambda: len(scores) == before + 1), f"no scores for frame {before}"
    return expected


def statuses_against(
    scores: list[Any], expected: list[FrameResult], method: str
) -> list[tuple[Any, FrameResult]]:
    """Each published status of ``method`` with the core's result, their sums checked equal."""
    assert len(expected) == len(scores)
    pairs = []
    for array, result in zip(scores, expected, strict=True):
        status = statuses(array)[method]
        assert convert.status_level(status) == OK, status.message
        rebuilt = scores_from_status(convert.status_values(status))
        np.testing.assert_array_equal(rebuilt.sums, result.scores[method].sums)
        pairs.append((status, result))
    return pairs


def test_point_cloud_ground_truth_equals_the_core(ros: Ros) -> None:
    topics = Topics("cloud")
    node = ros.evaluator(
        methods=[f"good:{topics.good}"],
        gt_topic=topics.gt,
        gt_kind="pointcloud",
        lidar_extrinsic=" ".join(map(str, LIDAR_TO_OPTICAL.reshape(-1).tolist())),
        cloud_filter="5,0.1",
        left_camera_info=topics.left,
        right_camera_info=topics.right,
    )
    assert node.config.extrinsic == tuple(LIDAR_TO_OPTICAL.reshape(-1))
    types = {
        topics.gt: sensor_msgs.PointCloud2,
        topics.left: sensor_msgs.CameraInfo,
        topics.right: sensor_msgs.CameraInfo,
        topics.good: stereo_msgs.DisparityImage,
    }
    pubs = make_publishers(ros, types)
    scores = scores_once_matched(ros, node, pubs, list(pubs))
    core = EvaluationCore(node.config)
    for topic, right in ((topics.left, False), (topics.right, True)):
        msg = camera_info_msg(START_NS, right)
        pubs[topic].publish(msg)
        core.push(topic, msg)
    assert ros.spin_until(lambda: node._live.core.camera() is not None)

    expected: list[FrameResult] = []
    for k in range(3):
        stamp = START_NS + k * FRAME_NS
        cloud = cloud_msg(lidar_scene(k), stamp)
        projected = core.cloud_disparity(cloud, core.camera(), (H, W)).disparity
        assert (projected > 0).sum() > 200
        disparity = disparity_msg(estimate(projected, 0.3, k), stamp)
        expected += publish_frame(
            ros, pubs, core, scores, [(topics.gt, cloud), (topics.good, disparity)]
        )
    for status, result in statuses_against(scores, expected, "good"):
        rebuilt = scores_from_status(convert.status_values(status))
        assert "0-10m" in rebuilt.criteria
        assert "irmse" in result.scores["good"].measures


def test_point_cloud_without_extrinsic_needs_tf2_or_the_parameter(ros: Ros) -> None:
    from dispeval_ros.errors import ConfigurationError

    if importlib.util.find_spec("tf2_ros") or importlib.util.find_spec("tf2_msgs"):
        pytest.skip("tf2 is installed: /tf_static is read")
    topics = Topics("notf")
    with pytest.raises(ConfigurationError, match="set the parameter lidar_extrinsic"):
        ros.evaluator(
            methods=[f"good:{topics.good}"],
            gt_topic=topics.gt,
            gt_kind="pointcloud",
            left_camera_info=topics.left,
            right_camera_info=topics.right,
        )
    with pytest.raises(ConfigurationError, match="lidar_extrinsic"):
        ros.evaluator(
            methods=[f"good:{topics.good}"],
            gt_topic=topics.gt,
            gt_kind="pointcloud",
            lidar_extrinsic="1 2 3",
            left_camera_info=topics.left,
            right_camera_info=topics.right,
        )


def test_bag_replay_with_point_cloud_reads_tf_static_from_the_bag(ros: Ros, tmp_path: Path) -> None:
    from dispeval_ros.cli.main import main
    from dispeval_ros.offline.make_bag import CLOUD_TOPIC, LEFT_INFO, RIGHT_INFO, disparity_topic
    from dispeval_ros.offline.sample import find_sample_bag

    bag = find_sample_bag()
    assert bag is not None
    methods = {name: disparity_topic(name) for name in ("sgbm", "bm_fast")}
    out = tmp_path / "bag"
    args = ["bag", str(bag), "--gt-cloud", CLOUD_TOPIC, "--camera-info", LEFT_INFO, RIGHT_INFO]
    for name, topic in methods.items():
        args += ["--method", f"{name}={topic}"]
    assert main([*args, "--out", str(out), "--quiet"]) == 0
    with ResultsStore.open(out) as store:
        (sequence,) = store.sequences()
        expected = {stamp: store.frame_scores(sequence, stamp) for stamp in store.stamps(sequence)}
    assert len(expected) == 25

    scores = ros.collect(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", evaluator_node.RESULTS_QOS
    )
    stop = __import__("threading").Event()
    node = ros.add(
        evaluator_node.EvaluatorNode(
            stop=stop,
            context=ros.context,
            parameter_overrides=[
                Parameter("methods", value=[f"{n}:{t}" for n, t in methods.items()]),
                Parameter("gt_topic", value=CLOUD_TOPIC),
                Parameter("gt_kind", value="pointcloud"),
                Parameter("left_camera_info", value=LEFT_INFO),
                Parameter("right_camera_info", value=RIGHT_INFO),
                Parameter("bag", value=str(bag)),
                Parameter("bag_rate", value=0.0),
                Parameter("bag_wait_subscribers", value=1),
            ],
        )
    )
    assert node.config.tf_topic == "/tf_static"
    assert ros.spin_until(stop.is_set, 120), "the replay did not end"
    node.finish()
    assert ros.spin_until(lambda: len(scores) == 26)  # 25 frames and the final counts
    for array in scores:
        stamp = stamp_ns(array.header)
        for method, status in statuses(array).items():
            assert convert.status_level(status) == OK, status.message
            rebuilt = scores_from_status(convert.status_values(status))
            np.testing.assert_array_equal(rebuilt.sums, expected[stamp][method].sums)


def test_tf2_ros_lookup_glue(monkeypatch: pytest.MonkeyPatch) -> None:
    """The tf2_ros path (tf2_ros is not on PyPI: a stand-in module with its API)."""
    import sys
    from types import SimpleNamespace

    from dispeval_ros.core.transforms import matrix_from_pose
    from dispeval_ros.errors import CalibrationError
    from dispeval_ros.ros import static_tf

    class TransformException(Exception):
        pass

    class Buffer:
        def lookup_transform(self, target: str, source: str, time: Any) -> Any:
            if source != "velodyne":
                raise TransformException(f'"{source}" passed to lookupTransform does not exist')
            return SimpleNamespace(
                transform=SimpleNamespace(
                    translation=SimpleNamespace(x=0.1, y=-0.2, z=0.3),
                    rotation=SimpleNamespace(x=0.0, y=0.0, z=0.0, w=1.0),
                )
            )

        def all_frames_as_string(self) -> str:
            return "Frame velodyne exists with parent base_link.\n"

    listeners: list[Any] = []
    fake = SimpleNamespace(
        Buffer=Buffer,
        StaticTransformListener=lambda buffer, node: listeners.append((buffer, node)) or "L",
        TransformException=TransformException,
    )
    monkeypatch.setitem(sys.modules, "tf2_ros", fake)
    found = static_tf.tf2_lookup("node")
    assert found is not None
    lookup, listener = found
    assert listener == "L"
    assert listeners[0][1] == "node"
    np.testing.assert_array_equal(
        lookup("stereo_left", "velodyne"), matrix_from_pose([0.1, -0.2, 0.3], [0, 0, 0, 1])
    )
    with pytest.raises(CalibrationError) as error:
        lookup("stereo_left", "os_lidar")
    message = str(error.value)
    assert "cloud frame 'os_lidar'" in message
    assert "camera frame 'stereo_left'" in message
    assert "Frame velodyne exists with parent base_link." in message


# -- ground-truth-free measures from the rectified images ---------------------------------------


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
