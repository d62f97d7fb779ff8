"""``dispeval bag --egomotion``: the ego-motion residual from the bag's own /tf, per pair.

make-bag's synthetic drive records the drive's exact motion on /tf (odom → base_link) and the
camera's mount on /tf_static. The residual scored from them equals the one scored with the
exact motion given directly (test/stream/test_pairs_egomotion.py checks that one against
``egomotion_residual``), a bag cut into many units gives the rows of one unit, and a bag
without /tf is refused in one line.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

import numpy as np
import pytest
from bag_support import drive_motion_lookup

from dispeval_ros.cli.main import main
from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import (
    GT_TOPIC,
    LEFT_IMAGE,
    LEFT_INFO,
    RIGHT_IMAGE,
    RIGHT_INFO,
    disparity_topic,
    estimates_from,
    synthetic_frames,
    write_bag,
)
from dispeval_ros.stream.core import CoreConfig, EvaluationCore
from dispeval_ros.testbed.methods import default_methods

FRAMES, WIDTH, HEIGHT, SEED = 5, 620, 188, 4


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The drive with its exact disparity published as method ``truth``, and its /tf."""
    root = tmp_path_factory.mktemp("egobag")
    frames = list(synthetic_frames(FRAMES, WIDTH, HEIGHT, 10.0, seed=SEED))
    (root / "truth").mkdir()
    for index, frame in enumerate(frames):
        np.save(root / "truth" / f"{index:06d}.npy", np.asarray(frame.gt, dtype=np.float32))
    write_bag(
        root / "drive", iter(frames), storage="rosbag2-sqlite3",
        methods=default_methods(WIDTH)[:1], estimates=[estimates_from("truth", root / "truth")],
    )  # fmt: skip
    return root / "drive"


def command(bag: Path, out: Path, *extra: str) -> list[str]:
    return [
        "bag", str(bag), "--gt", GT_TOPIC, "--method", f"truth={disparity_topic('truth')}",
        "--camera-info", LEFT_INFO, RIGHT_INFO, "--left-image", LEFT_IMAGE,
        "--right-image", RIGHT_IMAGE, "--egomotion", "--out", str(out), "--quiet", *extra,
    ]  # fmt: skip


def rows(folder: Path) -> list[tuple]:
    connection = sqlite3.connect(folder / "results.sqlite")
    found = connection.execute("SELECT * FROM motion_pairs ORDER BY stamp, method").fetchall()
    connection.close()
    return found


def test_the_residual_from_the_bags_tf_is_that_of_the_exact_motion_in_any_units(
    drive: Path, tmp_path: Path
) -> None:
    many = tmp_path / "many"
    assert main(command(drive, many, "--slice", "0.15")) == 0
    assert main(command(drive, tmp_path / "one", "--slice", "100")) == 0
    with ResultsStore.open(many) as store:
        assert len(store.done_units("drive")) >= 3
        stored = store.motion_pairs("drive")
        assert store.problems() == []
    assert rows(many) == rows(tmp_path / "one")
    assert stored is not None
    pairs, from_tf = stored["truth"]
    assert pairs == FRAMES - 1
    config = CoreConfig(
        methods={"truth": disparity_topic("truth")}, gt_topic=GT_TOPIC,
        left_info_topic=LEFT_INFO, right_info_topic=RIGHT_INFO, left_image_topic=LEFT_IMAGE,
        right_image_topic=RIGHT_IMAGE, egomotion=True,
    )  # fmt: skip
    core = EvaluationCore(config)
    assert core.pairs is not None
    core.pairs.motion = drive_motion_lookup(WIDTH, HEIGHT, SEED)  # instead of the bag's /tf
    exact = []
    topics = [t for t in config.topics if not t.startswith("/tf")]
    with BagSource(drive) as source:
        for topic, log_ns, msg in source.messages(topics):
            for frame_set in core.push(topic, msg, log_ns):
                exact += core.pair(core.score(frame_set)).motion_pairs
    total = exact[0].sums
    for pair in exact[1:]:
        total = total + pair.sums
    assert from_tf.criteria == total.criteria
    np.testing.assert_allclose(from_tf.sums, total.sums, rtol=1e-6)
    assert from_tf.summary("all")["bad_0.5"] < 10  # the exact disparity fits its exact motion


def test_a_bag_without_tf_is_one_line(
    drive: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from dispeval_ros.offline.make_bag import synthetic_frames as frames_of

    bag = tmp_path / "still"
    write_bag(
        bag, frames_of(2, 192, 64, 10.0, seed=1, odometry=False), storage="rosbag2-sqlite3",
        methods=default_methods(192)[:1],
    )  # fmt: skip
    args = command(bag, tmp_path / "out")
    args[args.index(f"truth={disparity_topic('truth')}")] = "bm=/stereo/bm_fast/disparity"
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "has no /tf to take the camera's motion from (--egomotion)" in err
    assert not (tmp_path / "out").exists()
