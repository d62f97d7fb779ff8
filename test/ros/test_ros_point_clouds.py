"""Robot mode with LiDAR ground truth: point clouds, the extrinsic from tf2 or the parameter,
``/tf_static`` from a bag (needs ROS 2).

The harness and message builders: ros_nodes_support.py.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ros_nodes_support import (
    FRAME_NS,
    START_NS,
    H,
    Parameter,
    Topics,
    W,
    camera_info_msg,
    convert,
    diagnostic_msgs,
    disparity_msg,
    estimate,
    evaluator_node,
    make_publishers,
    publish_frame,
    scores_once_matched,
    sensor_msgs,
    statuses,
    statuses_against,
    stereo_msgs,
)
from ros_support import Ros

from dispeval_ros.io.messages import stamp_ns
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.stream.core import EvaluationCore, FrameResult
from dispeval_ros.stream.vectors import (
    OK,
    scores_from_status,
)

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
