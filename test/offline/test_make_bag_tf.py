"""A synthetic drive's bag carries its exact ego-motion on /tf (odom → base_link) and /tf_static.

The bag is read back with rosbags into a TransformHistory; the camera's motion between frames
is compared with the rig's own positions (world x right, y up, z forward; optical y down; the
rig never turns), written here, not with make-bag's code.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from dispeval_ros.core.transform_history import TransformHistory
from dispeval_ros.io.messages import stamp_ns, static_transforms_from_msg
from dispeval_ros.io.tf_messages import transforms_from_msg
from dispeval_ros.offline.make_bag import synthetic_frames, write_bag
from dispeval_ros.testbed import StereoMethod, driving_setup
from dispeval_ros.testbed.lidar import LidarModel

FRAMES, WIDTH, HEIGHT, FPS = 4, 96, 32, 10.0
_BM = StereoMethod("bm", "bm")


def _messages(bag: Path, topic: str) -> list[Any]:
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        return [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections)]


def _history(bag: Path) -> tuple[TransformHistory, list[int], str]:
    history = TransformHistory()
    for msg in _messages(bag, "/tf_static"):
        history.add_static(static_transforms_from_msg(msg))
    stamps = []
    for msg in _messages(bag, "/tf"):
        samples = transforms_from_msg(msg)
        assert history.extend(samples) == []
        stamps += [stamp for stamp, _ in samples]
    infos = _messages(bag, "/stereo/left/camera_info")
    assert [stamp_ns(info.header) for info in infos] == stamps  # /tf at each image's stamp
    return history, stamps, infos[0].header.frame_id


@pytest.mark.parametrize("lidar", [None, LidarModel(beams=4)], ids=["no-lidar", "lidar"])
def test_the_synthetic_drive_bag_carries_its_exact_motion(
    tmp_path: Path, lidar: LidarModel | None
) -> None:
    bag = tmp_path / "drive"
    frames = synthetic_frames(FRAMES, WIDTH, HEIGHT, FPS, seed=0, lidar=lidar)
    summary = write_bag(bag, frames, methods=[_BM])
    assert (summary["tf"], summary["tf_static"]) == ("/tf", "/tf_static")
    history, stamps, camera = _history(bag)
    _, rig = driving_setup(WIDTH, HEIGHT, FPS, 0)
    for first in range(FRAMES):
        for second in range(FRAMES):
            step = np.subtract(rig.at(second / FPS).position, rig.at(first / FPS).position)
            expected = np.eye(4)
            expected[:3, 3] = (step[0], -step[1], step[2])
            got = history.camera_motion(camera, stamps[first], stamps[second])
            np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)
    assert history.camera_motion(camera, stamps[0], stamps[1])[2, 3] > 0.5  # 8–12 m/s at 10 Hz
    assert history.fixed_frame(camera) == "odom"


def test_base_link_is_one_vehicle_frame_with_or_without_the_lidar(tmp_path: Path) -> None:
    mounts = []
    for lidar in (None, LidarModel(beams=4)):
        bag = tmp_path / ("lidar" if lidar else "plain")
        write_bag(bag, synthetic_frames(2, WIDTH, HEIGHT, FPS, 0, lidar), methods=[_BM])
        history, stamps, camera = _history(bag)
        mounts.append(history.lookup("odom", camera, stamps[1]))
    np.testing.assert_allclose(mounts[0], mounts[1], rtol=0, atol=1e-12)
    # The camera looks along base_link's x (forward): odom's +x, as the rig never turns.
    np.testing.assert_allclose(mounts[0][:3, 2], [1.0, 0.0, 0.0], atol=1e-12)


def test_without_odometry_there_is_no_tf(tmp_path: Path) -> None:
    bag = tmp_path / "drive"
    frames = synthetic_frames(2, WIDTH, HEIGHT, FPS, seed=0, odometry=False)
    summary = write_bag(bag, frames, methods=[_BM])
    assert "tf" not in summary
    assert "tf_static" not in summary
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        assert not {"/tf", "/tf_static"} & {c.topic for c in reader.connections}


def test_a_synthetic_bag_scores_ego_motion_from_its_tf(tmp_path: Path) -> None:
    """The true disparity moved by the bag's /tf lands on itself: 85 % of counted pixels < 0.01 px.

    The rest are the traffic's vehicles (they move), so a quantile, not the mean, is checked.
    The inverse motion (the wrong convention) fails it: the road maps onto itself under any
    motion along it, but the buildings and parked cars do not.
    """
    from dispeval_ros.core.egomotion import PinholeCamera, egomotion_residual, prepare_frame
    from dispeval_ros.core.transforms import invert_rigid
    from dispeval_ros.io.messages import camera_from_infos, image_from_msg

    bag = tmp_path / "drive"
    write_bag(bag, synthetic_frames(3, 620, 188, FPS, seed=0), methods=[_BM])
    history, stamps, camera = _history(bag)
    left_info, right_info = (
        _messages(bag, f"/stereo/{side}/camera_info")[0] for side in ("left", "right")
    )
    pinhole = PinholeCamera(
        camera_from_infos(left_info, right_info), float(left_info.k[2]), float(left_info.k[5])
    )
    frames = [
        prepare_frame(image_from_msg(gt).array, image_from_msg(left).array)
        for gt, left in zip(
            _messages(bag, "/stereo/ground_truth/disparity"),
            _messages(bag, "/stereo/left/image_rect"),
            strict=True,
        )
    ]
    for later in (1, 2):
        motion = history.camera_motion(camera, stamps[0], stamps[later])
        quantiles = []
        for moved in (motion, invert_rigid(motion)):
            result = egomotion_residual(frames[0], frames[later], moved, pinhole, keep_maps=True)
            status, residual, _ = result.maps
            quantiles.append(float(np.percentile(np.abs(residual[status == 0]), 85)))
        assert quantiles[0] < 0.01
        assert quantiles[1] > 0.5


def test_make_bag_says_where_the_motion_is(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from dispeval_ros.cli.main import main

    size = ["--frames", "2", "--width", "64", "--height", "32"]
    assert main(["make-bag", str(tmp_path / "plain"), *size, "--no-lidar"]) == 0
    assert "\nego-motion: /tf (odom → base_link), /tf_static\n" in capsys.readouterr().out
    assert main(["make-bag", str(tmp_path / "lidar"), *size]) == 0
    assert "with /tf_static; ego-motion on /tf (odom → base_link)\n" in capsys.readouterr().out
