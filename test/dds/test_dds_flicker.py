"""``dispeval live --flicker`` over Cyclone DDS stores the windows ``dispeval bag`` stores.

make-bag's rig standing still (``make-bag --static``: one frame recorded 6 times with fresh
sensor noise, the OpenCV method run on each) played over DDS: with windows of 4 frames the
first window closes with its 4th frame and the second (2 frames) when the session stops; both
reach the results database with the sums of ``dispeval bag --flicker 4`` on the same bag.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from test_dds import localhost, needs_dds, transports, wait_until  # noqa: F401 (fixtures)

from dispeval_ros.cli.main import main
from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import (
    GT_TOPIC,
    LEFT_IMAGE,
    LEFT_INFO,
    RIGHT_IMAGE,
    RIGHT_INFO,
    synthetic_frames,
    write_bag,
)
from dispeval_ros.offline.static_bag import static_frames

DISPARITY = "stereo_msgs/msg/DisparityImage"


@needs_dds
def test_live_flicker_over_dds_matches_dispeval_bag(
    transports: tuple[Any, Any],  # noqa: F811 (the fixture of test_dds)
    tmp_path: Path,
) -> None:
    from dispeval_ros.cli.live_cmd import live_record
    from dispeval_ros.dds.evaluator import warm_up
    from dispeval_ros.dds.player import BagPlayer
    from dispeval_ros.dds.session import LiveSession
    from dispeval_ros.stream.core import CoreConfig
    from dispeval_ros.stream.summarizer import SummarizerConfig
    from dispeval_ros.testbed.methods import default_methods

    first = next(iter(synthetic_frames(1, 320, 96, 10.0, seed=4, odometry=False)))
    bag = tmp_path / "still"
    write_bag(bag, static_frames(first, 6, 10.0, 2), storage="rosbag2-sqlite3",
              methods=default_methods(320)[:1])  # fmt: skip
    with BagSource(bag) as source:
        (method,) = [t for t, i in source.topics.items() if i.msgtype == DISPARITY]
    name = method.split("/")[2]
    config = CoreConfig(
        methods={name: method}, gt_topic=GT_TOPIC, left_info_topic=LEFT_INFO,
        right_info_topic=RIGHT_INFO, left_image_topic=LEFT_IMAGE, right_image_topic=RIGHT_IMAGE,
        flicker=4,
    )  # fmt: skip
    reference = tmp_path / "bag"
    argv = ["bag", str(bag), "--gt", GT_TOPIC, "--method", f"{name}={method}", "--camera-info"]
    argv += [LEFT_INFO, RIGHT_INFO, "--left-image", LEFT_IMAGE, "--right-image", RIGHT_IMAGE]
    assert main([*argv, "--flicker", "4", "--out", str(reference), "--quiet"]) == 0
    with ResultsStore.open(reference) as store:
        (sequence,) = store.sequences()
        expected = store.flicker_series(sequence)
    assert expected is not None
    assert [w.frames for w in expected[name]] == [4, 2]

    publisher, _ = transports
    warm_up(config)
    out = tmp_path / "live"
    session = LiveSession(publisher.domain, config, SummarizerConfig(out), live_record(config),
                          queue_size=64)  # fmt: skip
    try:
        session.start()
        player = BagPlayer(publisher, bag, list(config.topics))
        assert player.wait_matched(10) == []
        player.play(rate=1.0)
        assert wait_until(lambda: session.status().frames >= 6, 30), session.status()
    finally:
        session.stop()
    with ResultsStore.open(out) as store:
        (sequence,) = store.sequences()
        got = store.flicker_series(sequence)
        assert store.problems() == []
    assert got is not None
    assert [(w.frames, w.stamp - w.start) for w in got[name]] == [
        (w.frames, w.stamp - w.start) for w in expected[name]
    ]
    for mine, theirs in zip(got[name], expected[name], strict=True):
        np.testing.assert_array_equal(mine.sums.sums, theirs.sums.sums)
