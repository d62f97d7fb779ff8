"""Frames scored side by side in one process give the rows of one thread, each with its own camera.

A frame is scored on a thread while later messages are pushed, so it must take the CameraInfo
pair that was current when it was joined, not the latest one: here the baseline changes every
frame, which changes every SZE.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from dispeval_ros.core import Camera
from dispeval_ros.io.bags import BagWriter
from dispeval_ros.io.encoders import camera_info_to_msg, disparity_to_msg, image_to_msg
from dispeval_ros.offline import units as units_module
from dispeval_ros.offline.units import UnitRows, evaluate_unit, plan_bag
from dispeval_ros.stream.core import CoreConfig

HUMBLE = get_typestore(Stores.ROS2_HUMBLE)
T0 = 1_700_000_000_000_000_000
STEP = 100_000_000
FRAMES = 9
H, W = 24, 40
CONFIG = CoreConfig(
    methods={"a": "/a/disparity", "b": "/b/disparity"},
    gt_topic="/gt",
    left_info_topic="/left/info",
    right_info_topic="/right/info",
)


def camera(index: int) -> Camera:
    return Camera(500.0, 0.1 + 0.05 * index)


def maps(index: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    rng = np.random.default_rng(index)
    gt = rng.uniform(2.0, 60.0, (H, W)).astype(np.float32)
    estimates = {}
    for offset, method in enumerate(CONFIG.methods):
        estimate = (gt + rng.normal(0, 1 + offset, gt.shape)).astype(np.float32)
        estimate[rng.random(gt.shape) < 0.2] = -1.0  # holes: invalid below min_disparity
        estimates[method] = estimate
    return gt, estimates


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("side") / "drive"
    with BagWriter(path, "rosbag2-mcap", compress=False) as writer:
        for topic, msgtype in CONFIG.topics.items():
            writer.add_topic(topic, msgtype)
        for index in range(FRAMES):
            stamp = T0 + index * STEP
            cam = camera(index)
            for topic, right in (("/left/info", False), ("/right/info", True)):
                writer.write(topic, stamp, camera_info_to_msg(HUMBLE, cam, W, H, stamp, "c", right))
            gt, estimates = maps(index)
            writer.write("/gt", stamp, image_to_msg(HUMBLE, gt, stamp, "c", "32FC1"))
            for method, topic in CONFIG.methods.items():
                msg = disparity_to_msg(HUMBLE, estimates[method], stamp, "c", 500.0, 0.1, 0, 100)
                writer.write(topic, stamp, msg)
    return path


def test_frames_side_by_side_give_one_threads_rows_with_each_frames_camera(bag: Path) -> None:
    (unit,) = plan_bag(bag, "drive", CONFIG, 10 * FRAMES * STEP).units
    alone = evaluate_unit(CONFIG, unit, 1)
    side_by_side = evaluate_unit(CONFIG, unit, 2)
    units_module.close_scoring_pools()
    assert [(f.stamp, f.method) for f in side_by_side.frames] == [
        (f.stamp, f.method) for f in alone.frames
    ]
    assert len(alone.frames) == FRAMES * len(CONFIG.methods)
    assert UnitRows.of(side_by_side).rows.frame_rows == UnitRows.of(alone).rows.frame_rows
    assert side_by_side.problems == alone.problems == []
    evaluator = CONFIG.evaluator()
    for frame in side_by_side.frames:
        index = (frame.stamp - T0) // STEP
        gt, estimates = maps(index)
        expected = evaluator.score(
            gt, estimates[frame.method], camera(index), est_range=(0.0, 100.0)
        )
        assert frame.scores.sums.tobytes() == expected.sums.tobytes()
    sze = [f.scores.sums for f in alone.frames if f.method == "a"]
    assert len({s.tobytes() for s in sze}) == FRAMES  # the camera changes every score
