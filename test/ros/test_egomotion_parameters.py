"""The evaluator's ``egomotion``, ``odometry_topic`` and ``camera_mount`` parameters, and the
motion source's odometry hooks they feed (no ROS needed: values and plain messages)."""

from __future__ import annotations

from types import SimpleNamespace as NS
from typing import Any

import numpy as np
import pytest

from dispeval_ros.core.transforms import StaticTransform, TransformTree, invert_rigid
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.ros import param_table, params
from dispeval_ros.stream.config import CoreConfig
from dispeval_ros.stream.motion import MotionSource

NS_PER_S = 1_000_000_000
MOUNT = np.array([[0, 0, 1, 0.3], [-1, 0, 0, 0.3], [0, -1, 0, 1.65], [0, 0, 0, 1]], float)
"""base_link → a forward-looking optical frame (x right, y down, z forward)."""


def values(**changes: Any) -> dict[str, Any]:
    table = {p.name: p.empty_default for p in param_table.EVALUATOR_PARAMETERS}
    table.update(
        methods=("sgbm:/sgbm",),
        gt_topic="/gt",
        left_camera_info="/left/info",
        right_camera_info="/right/info",
    )
    table.update(changes)
    return table


def test_egomotion_is_off_by_default_and_on_when_set() -> None:
    assert params.evaluator_options(values()).core.egomotion is False
    options = params.evaluator_options(
        values(egomotion=True, odometry_topic=" /odom ", camera_mount="0 0 1 0 0 0 1")
    )
    assert options.core.egomotion is True
    assert options.odometry_topic == "/odom"
    expected = np.eye(4)
    expected[2, 3] = 1.0  # 'x y z qx qy qz qw': 1 m along z, no rotation
    np.testing.assert_array_equal(np.reshape(options.camera_mount, (4, 4)), expected)
    assert params.evaluator_options(values(egomotion=True)).odometry_topic is None


@pytest.mark.parametrize(
    ("changes", "words"),
    [
        (
            {"egomotion": True, "left_camera_info": "", "right_camera_info": ""},
            "parameter egomotion moves each estimate by the camera's motion: give parameters "
            "left_camera_info and right_camera_info",
        ),
        ({"odometry_topic": "/odom"}, "parameter odometry_topic moves the camera for egomotion"),
        (
            {"egomotion": True, "camera_mount": "0 0 0 0 0 0 1"},
            "parameter camera_mount mounts the camera on the odometry's child frame: give "
            "odometry_topic too",
        ),
        (
            {"egomotion": True, "odometry_topic": "/odom", "camera_mount": "1 2 3"},
            "parameter camera_mount",
        ),
    ],
    ids=["no camera info", "odometry without egomotion", "mount without odometry", "bad mount"],
)
def test_what_does_not_apply_is_one_line_naming_the_parameter(
    changes: dict[str, Any], words: str
) -> None:
    with pytest.raises(ConfigurationError) as error:
        params.evaluator_options(values(**changes))
    assert words in str(error.value)
    assert "\n" not in str(error.value)
    assert "--" not in str(error.value)


def odometry(stamp: int, pose: np.ndarray, child: str = "base_link") -> Any:
    """A nav_msgs/Odometry as rclpy delivers it (attribute names only), of a pure translation."""
    x, y, z = pose[:3, 3]
    return NS(
        header=NS(stamp=NS(sec=stamp // NS_PER_S, nanosec=stamp % NS_PER_S), frame_id="odom"),
        child_frame_id=child,
        pose=NS(pose=NS(position=NS(x=x, y=y, z=z), orientation=NS(x=0.0, y=0.0, z=0.0, w=1.0))),
    )


def poses(*steps: float) -> list[np.ndarray]:
    out = []
    for step in steps:
        pose = np.eye(4)
        pose[0, 3] = step  # base_link drives along its x
        out.append(pose)
    return out


def test_odometry_and_the_mount_give_the_cameras_motion() -> None:
    source = MotionSource(TransformTree(), "/tf_static")
    source.mount = MOUNT
    drive = poses(0.0, 0.8, 1.7)
    for k, pose in enumerate(drive):
        source.push_odometry("/odom", odometry(k * NS_PER_S // 10, pose))
    assert not source.problems()
    assert source.ready(NS_PER_S // 5, "stereo_left")
    moved = source.camera_motion("stereo_left", 0, NS_PER_S // 10)
    expected = invert_rigid(drive[0] @ MOUNT) @ (drive[1] @ MOUNT)
    np.testing.assert_allclose(moved, expected, atol=1e-12)
    np.testing.assert_allclose(moved[:3, 3], [0.0, 0.0, 0.8], atol=1e-12)  # forward: +z
    assert not source.ready(NS_PER_S, "stereo_left")  # no odometry that late


def test_without_a_mount_the_odometrys_child_must_be_the_camera() -> None:
    source = MotionSource(TransformTree(), "/tf_static")
    for k, pose in enumerate(poses(0.0, 0.5)):
        source.push_odometry("/odom", odometry(k * NS_PER_S // 10, pose, "stereo_left"))
    moved = source.camera_motion("stereo_left", 0, NS_PER_S // 10)
    np.testing.assert_allclose(moved[:3, 3], [0.5, 0.0, 0.0], atol=1e-12)
    other = MotionSource(TransformTree(), "/tf_static")
    for k, pose in enumerate(poses(0.0, 0.5)):
        other.push_odometry("/odom", odometry(k * NS_PER_S // 10, pose))
    with pytest.raises(Exception, match="stereo_left"):
        other.camera_motion("stereo_left", 0, NS_PER_S // 10)


def test_a_mount_from_tf_static_is_kept_and_a_bad_odometry_is_noted() -> None:
    static = TransformTree()
    static.add([StaticTransform("base_link", "stereo_left", MOUNT)])
    source = MotionSource(static, "/tf_static")
    source.mount = np.eye(4)  # ignored: /tf_static already mounts the camera
    for k, pose in enumerate(poses(0.0, 0.8)):
        source.push_odometry("/odom", odometry(k * NS_PER_S // 10, pose))
    source.push_odometry("/odom", NS(header=NS(frame_id="odom")))  # no stamp, no pose
    moved = source.camera_motion("stereo_left", 0, NS_PER_S // 10)
    np.testing.assert_allclose(moved[:3, 3], [0.0, 0.0, 0.8], atol=1e-12)
    [line] = source.problems()
    assert line.startswith("transforms: Odometry on /odom")


def test_the_core_takes_its_motion_from_the_source_with_its_hooks() -> None:
    from dispeval_ros.stream.core import EvaluationCore

    config = CoreConfig(
        methods={"a": "/a"},
        gt_topic="/gt",
        left_info_topic="/l",
        right_info_topic="/r",
        egomotion=True,
    )
    core = EvaluationCore(config)
    assert core.motion is not None
    assert core.pairs is not None
    core.motion.mount = MOUNT
    for k, pose in enumerate(poses(0.0, 0.8)):
        core.motion.push_odometry("/odom", odometry(k * NS_PER_S // 10, pose))
    moved = core.pairs.motion("stereo_left", 0, NS_PER_S // 10)  # type: ignore[misc]
    np.testing.assert_allclose(moved[:3, 3], [0.0, 0.0, 0.8], atol=1e-12)
