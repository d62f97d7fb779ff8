"""The evaluator node with ``egomotion`` over real rclpy: a short synthetic drive published with
its exact motion as ``nav_msgs/Odometry`` (odom → base_link) and the camera's mount as the
``camera_mount`` parameter. The node's ``/dispeval/scores`` carry each pair's ego-motion
residual exactly as the core fed the same messages scores it (so the node adds no logic), the
true disparity's is near 0 and a noisy one's is not; frames whose motion the odometry does not
reach are one problem status per pair, and the node goes on; a looped replay of a bag with /tf
finds the motion in every pass (needs ROS 2 and nav_msgs)."""

from __future__ import annotations

from functools import partial
from typing import Any

import numpy as np
import pytest
from bag_support import noisy_drive_bag
from ros_nodes_support import (
    convert,
    diagnostic_msgs,
    evaluator_node,
    make_publishers,
    rig_camera_info,
    sensor_msgs,
    statuses,
    stereo_msgs,
)
from ros_support import Ros, ros_import

from dispeval_ros.offline.make_bag import (
    CAMERA_FRAME,
    GT_TOPIC,
    LEFT_IMAGE,
    LEFT_INFO,
    ODOM_FRAME,
    RIGHT_IMAGE,
    RIGHT_INFO,
    START_NS,
    disparity_topic,
    synthetic_frames,
)
from dispeval_ros.stream.core import CoreConfig, EvaluationCore, FrameResult
from dispeval_ros.stream.vectors import read_pairs

nav_msgs = ros_import("nav_msgs.msg")
geometry_msgs = ros_import("geometry_msgs.msg")

FRAMES, WIDTH, HEIGHT, FPS, SEED = 4, 320, 96, 10.0, 4
NOISE = {"truth": 0.0, "noisy": 0.5}
"""px of Gaussian noise on the GT, drawn anew in each frame."""


class DriveTopics:
    """The drive's input topics (unique per test)."""

    def __init__(self, name: str) -> None:
        base = f"/dispeval_test_ego_{name}"
        self.gt = f"{base}/ground_truth"
        self.left, self.right = f"{base}/left/camera_info", f"{base}/right/camera_info"
        self.methods = {m: f"{base}/{m}/disparity" for m in NOISE}
        self.odometry = f"{base}/odom"
        self.images = (f"{base}/left/image_rect", f"{base}/right/image_rect")


@pytest.fixture(scope="module")
def drive() -> list[Any]:
    return list(synthetic_frames(FRAMES, WIDTH, HEIGHT, FPS, seed=SEED))


def stamp_of(frame: Any) -> int:
    return START_NS + round(frame.stamp * 1e9)


def camera_info(frame: Any, right: bool) -> Any:
    return rig_camera_info(frame, stamp_of(frame), right, CAMERA_FRAME)


def disparity(frame: Any, values: np.ndarray) -> Any:
    stamp = stamp_of(frame)
    return stereo_msgs.DisparityImage(
        header=convert.header_msg(stamp, CAMERA_FRAME),
        image=convert.image_msg(values, stamp, CAMERA_FRAME, "32FC1"),
        f=float(frame.camera.f),
        t=float(frame.camera.baseline),
        min_disparity=0.0,
        max_disparity=float(WIDTH),
        delta_d=1.0 / 16.0,
    )


def odometry(frame: Any) -> Any:
    """odom → base_link at the frame's stamp: the drive's exact motion."""
    pose = frame.odometry
    w, x, y, z = _quaternion(pose[:3, :3])
    return nav_msgs.Odometry(
        header=convert.header_msg(stamp_of(frame), ODOM_FRAME),
        child_frame_id="base_link",
        pose=geometry_msgs.PoseWithCovariance(
            pose=geometry_msgs.Pose(
                position=geometry_msgs.Point(x=pose[0, 3], y=pose[1, 3], z=pose[2, 3]),
                orientation=geometry_msgs.Quaternion(x=x, y=y, z=z, w=w),
            )
        ),
    )


def _quaternion(rotation: np.ndarray) -> tuple[float, float, float, float]:
    """(w, x, y, z) of a proper rotation (the drive's rig turns little: w > 0)."""
    w = np.sqrt(max(0.0, 1.0 + np.trace(rotation))) / 2.0
    x = (rotation[2, 1] - rotation[1, 2]) / (4.0 * w)
    y = (rotation[0, 2] - rotation[2, 0]) / (4.0 * w)
    z = (rotation[1, 0] - rotation[0, 1]) / (4.0 * w)
    return float(w), float(x), float(y), float(z)


def frame_messages(topics: DriveTopics, frame: Any, index: int) -> list[tuple[str, Any]]:
    gt = np.asarray(frame.gt, dtype=np.float32)
    rng = np.random.default_rng(100 + index)
    stamp = stamp_of(frame)
    messages = [(topics.gt, convert.image_msg(gt, stamp, CAMERA_FRAME, "32FC1"))]
    for topic, image in zip(topics.images, (frame.left, frame.right), strict=True):
        messages.append((topic, convert.image_msg(image, stamp, CAMERA_FRAME, "mono8")))
    for method, noise in NOISE.items():
        values = gt + rng.normal(0.0, noise, gt.shape).astype(np.float32) * (noise > 0)
        messages.append((topics.methods[method], disparity(frame, values.astype(np.float32))))
    return messages


def run_drive(
    ros: Ros, name: str, drive: list[Any], with_odometry: int
) -> tuple[Any, list[Any], list[FrameResult]]:
    """Publish the drive (odometry for its first ``with_odometry`` frames) to a node with
    egomotion; check each scores array against the core fed the same messages."""
    topics = DriveTopics(name)
    mount = drive[0].camera_mount
    node = ros.evaluator(
        methods=[f"{m}:{t}" for m, t in topics.methods.items()],
        gt_topic=topics.gt,
        left_camera_info=topics.left,
        right_camera_info=topics.right,
        left_image_topic=topics.images[0],
        right_image_topic=topics.images[1],
        egomotion=True,
        odometry_topic=topics.odometry,
        camera_mount=" ".join(repr(float(v)) for v in mount.reshape(-1)),
    )
    assert node.config.egomotion
    assert node.options.odometry_topic == topics.odometry
    types = {topics.gt: sensor_msgs.Image, topics.left: sensor_msgs.CameraInfo}
    types |= {topics.right: sensor_msgs.CameraInfo, topics.odometry: nav_msgs.Odometry}
    types |= dict.fromkeys(topics.methods.values(), stereo_msgs.DisparityImage)
    types |= dict.fromkeys(topics.images, sensor_msgs.Image)
    pubs = make_publishers(ros, types)
    scores = ros.collect(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", evaluator_node.RESULTS_QOS
    )
    assert ros.spin_until(lambda: all(p.get_subscription_count() > 0 for p in pubs.values()))
    assert ros.spin_until(lambda: node._scores_pub.get_subscription_count() > 0)
    core = EvaluationCore(CoreConfig(
        methods=topics.methods, gt_topic=topics.gt, left_info_topic=topics.left,
        right_info_topic=topics.right, left_image_topic=topics.images[0],
        right_image_topic=topics.images[1], egomotion=True,
    ))  # fmt: skip
    assert core.motion is not None
    assert node._live.core.motion is not None
    core.motion.mount = mount
    for topic, right in ((topics.left, False), (topics.right, True)):
        msg = camera_info(drive[0], right)
        pubs[topic].publish(msg)
        core.push(topic, msg)
    assert ros.spin_until(lambda: node._live.core.camera() is not None)
    expected: list[FrameResult] = []
    for index, frame in enumerate(drive):
        if index < with_odometry:
            msg = odometry(frame)
            pubs[topics.odometry].publish(msg)
            core.motion.push_odometry(topics.odometry, msg)
            assert ros.spin_until(partial(node._live.core.motion.history.ready, stamp_of(frame)))
        for topic, msg in frame_messages(topics, frame, index):
            pubs[topic].publish(msg)
            expected += [core.pair(core.score(s)) for s in core.push(topic, msg)]
        assert ros.spin_until(lambda n=index + 1: len(scores) == n), f"no scores for {index}"
    return node, scores, expected


def motion_of(array: Any) -> dict[str, Any]:
    """Method → (previous stamp, ego-motion sums) of the statuses that carry them, read as
    every summarizer reads them (egomotion without temporal: no pair keys beside them)."""
    pairs: dict[str, Any] = {}
    found: dict[str, Any] = {}
    for name, status in statuses(array).items():
        if name in NOISE:
            read_pairs(convert.status_record(status), pairs, found)
    assert not pairs
    return found


def problems_of(array: Any) -> list[str]:
    return [s.message for s in array.status if "no ego-motion pair" in s.message]


def test_the_scores_carry_the_cores_egomotion_residual(ros: Ros, drive: list[Any]) -> None:
    node, scores, expected = run_drive(ros, "exact", drive, with_odometry=FRAMES)
    assert [len(r.motion_pairs) for r in expected] == [0, 2, 2, 2]
    for array, result in zip(scores, expected, strict=True):
        assert not problems_of(array)
        got = motion_of(array)
        assert sorted(got) == sorted(p.method for p in result.motion_pairs)
        for pair in result.motion_pairs:
            previous, sums = got[pair.method]
            assert previous == pair.previous
            np.testing.assert_array_equal(sums.sums, pair.sums.sums)
    last = {p.method: p.sums.summary("all")["bad_0.5"] for p in expected[-1].motion_pairs}
    # the true map fits the exact motion within 0.5 px but where things move (as in
    # test/stream/test_pairs_egomotion.py); per-frame noise does not
    assert last["truth"] < 10
    assert last["noisy"] > 3 * last["truth"]
    assert node.frames_scored == FRAMES


def test_frames_the_odometry_does_not_reach_are_problems_per_pair(
    ros: Ros, drive: list[Any]
) -> None:
    node, scores, expected = run_drive(ros, "short", drive, with_odometry=2)
    assert [len(r.motion_pairs) for r in expected] == [0, 2, 0, 0]
    for array, result in zip(scores, expected, strict=True):
        wanted = [text for method, text in result.problems if "no ego-motion pair" in text]
        assert problems_of(array) == wanted
        assert sorted(motion_of(array)) == sorted(p.method for p in result.motion_pairs)
    assert [len(problems_of(a)) for a in scores] == [0, 0, 1, 1]  # one line per pair
    assert node.frames_scored == FRAMES  # every frame scored and published all the same


def test_a_looped_replay_finds_the_motion_in_every_pass(
    ros: Ros, drive: list[Any], tmp_path: Any
) -> None:
    """``bag_loop`` moves the /tf stamps with the frames' (else a later pass has no motion)."""
    bag = noisy_drive_bag(tmp_path, drive, NOISE, seed=2)
    scores = ros.collect(
        diagnostic_msgs.DiagnosticArray, "/dispeval/scores", evaluator_node.RESULTS_QOS
    )
    node = ros.evaluator(
        methods=[f"{m}:{disparity_topic(m)}" for m in NOISE],
        gt_topic=GT_TOPIC,
        left_camera_info=LEFT_INFO,
        right_camera_info=RIGHT_INFO,
        left_image_topic=LEFT_IMAGE,
        right_image_topic=RIGHT_IMAGE,
        egomotion=True,
        bag=str(bag),
        bag_rate=0.0,
        bag_loop=True,
        bag_exit=False,
        bag_wait_subscribers=1,
    )
    passes = 3
    assert ros.spin_until(lambda: len(scores) >= passes * FRAMES, timeout=60.0)
    node._stop.set()
    arrays = scores[: passes * FRAMES]
    moved = [sorted(motion_of(array)) for array in arrays]
    # each pass: its first frame starts a new run of pairs, the others carry both residuals
    assert moved == ([[]] + [sorted(NOISE)] * (FRAMES - 1)) * passes, moved
    first, later = (
        {m: s.sums for m, (_, s) in motion_of(arrays[k]).items()} for k in (1, FRAMES + 1)
    )
    for method in NOISE:  # the same frames and motion give the same residual in every pass
        np.testing.assert_array_equal(first[method], later[method])
