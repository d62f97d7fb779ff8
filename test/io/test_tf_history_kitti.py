"""The shared KITTI raw drive's bag: its /tf and /tf_static give the motion ``eval`` uses.

The bag is written by make-bag's writer from the drive (one cheap method: the transforms do not
depend on the methods), read back with rosbags into a :class:`TransformHistory`, and the
camera's motion between consecutive oxts stamps is compared with the bag's own edges composed
here (``(odom ← base_link)·(base_link ← camera)`` per stamp, numpy's inverse), to 1e-9, and with
the per-sample poses (``camera_poses`` then ``core.egomotion.camera_motion``). At the left
images' stamps the bag's motion is compared with what ``eval --scene DRIVE --egomotion`` takes
(``drive_motion``: the same TransformHistory built from the drive's files), pair by pair. Both
agree to 2e-7 only: KITTI's calibration rotations are orthonormal to about 1e-7 (``R·Rᵀ − I``
up to 9.6e-8 for base_link → camera, 7 printed digits), and a /tf quaternion carries the
nearest rotation, not the printed matrix (make-bag composes the mount from the two printed
transforms' rigid inverses, eval inverts their product: 4e-8 m apart on a translation).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bag_support import quaternion_matrix
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from dispeval_ros.core.egomotion import camera_motion
from dispeval_ros.core.transform_history import TransformHistory
from dispeval_ros.errors import ExtrapolationError
from dispeval_ros.io.kitti_raw import camera_poses, drive_motion, open_drive
from dispeval_ros.io.messages import static_transforms_from_msg
from dispeval_ros.io.tf_messages import transforms_from_msg
from dispeval_ros.offline.make_bag import (
    BASE_FRAME,
    CAMERA_FRAME,
    ODOM_FRAME,
    kitti_raw_frames,
    write_bag,
)
from dispeval_ros.testbed import StereoMethod

DRIVE = "kitti-raw-drive-0048/2011_09_26/2011_09_26_drive_0048_sync"


def _messages(bag: Path, topic: str) -> list[Any]:
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        return [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections)]


@pytest.mark.slow
@pytest.mark.data
def test_bag_tf_gives_the_motion_eval_uses(shared_data: Path, tmp_path: Path) -> None:
    drive = shared_data / DRIVE
    bag = tmp_path / "drive"
    write_bag(bag, kitti_raw_frames(drive), methods=[StereoMethod("bm", "bm")])
    history = TransformHistory()
    for msg in _messages(bag, "/tf_static"):
        history.add_static(static_transforms_from_msg(msg, "/tf_static"))
    stamps, odometry = [], []
    for msg in _messages(bag, "/tf"):
        samples = transforms_from_msg(msg, "/tf")
        assert history.extend(samples) == []
        stamps += [stamp for stamp, _ in samples]
        odometry += [
            quaternion_matrix(t.transform.translation, t.transform.rotation) for t in msg.transforms
        ]
    camera = _messages(bag, "/stereo/left/camera_info")[0].header.frame_id
    (mount,) = [
        quaternion_matrix(t.transform.translation, t.transform.rotation)
        for msg in _messages(bag, "/tf_static")
        for t in msg.transforms
        if (t.header.frame_id, t.child_frame_id) == ("base_link", camera)
    ]
    carried = [pose @ mount for pose in odometry]
    poses = camera_poses(open_drive(drive))
    assert len(stamps) == len(poses) == 11
    for k in range(len(stamps) - 1):
        got = history.camera_motion(camera, stamps[k], stamps[k + 1])
        composed = np.linalg.inv(carried[k]) @ carried[k + 1]
        np.testing.assert_allclose(got, composed, rtol=0, atol=1e-9)
        eval_motion = camera_motion(poses[k], poses[k + 1])
        np.testing.assert_allclose(got, eval_motion, rtol=0, atol=2e-7)
        # About 0.74 m forward per 0.1 s, along the optical axis.
        assert 0.6 < got[2, 3] < 0.9
    assert history.ready(stamps[-1], camera)
    assert not history.ready(stamps[-1] + 1, camera)
    # eval's motion of each pair, at the left images' stamps, against the bag's there
    opened = open_drive(drive)
    motion = drive_motion(opened, fixed=ODOM_FRAME, base=BASE_FRAME, camera=CAMERA_FRAME)
    images = opened.streams["image_02"].stamps
    assert motion.stamps == images
    for k in range(1, len(images) - 1):
        from_bag = history.camera_motion(camera, images[k], images[k + 1])
        from_eval = motion.between(k, k + 1)
        np.testing.assert_allclose(from_eval, from_bag, rtol=0, atol=2e-7)
        at_samples = camera_motion(poses[k], poses[k + 1])
        assert np.abs(from_bag[:3, 3] - at_samples[:3, 3]).max() > 0.02  # the stamps matter
    # the first image is 12.7 ms before the first oxts sample: neither path extrapolates
    for lookup in (lambda: history.camera_motion(camera, images[0], images[1]),
                   lambda: motion.between(0, 1)):  # fmt: skip
        with pytest.raises(ExtrapolationError, match=r"before its oldest sample .* 12\.698 ms"):
            lookup()
