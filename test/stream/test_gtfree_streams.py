"""Ground-truth-free measures in the stream core and ``dispeval bag`` (the sample bag's images).

The rclpy node is tested in test_ros_gt_free.py and ``dispeval live`` over DDS in test_dds.py
(modes ``images`` and ``no-gt``), both against the same ``dispeval bag`` numbers.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore
from sample_feed import sample_bag, sample_config, stored_scores

from dispeval_ros.cli.main import main
from dispeval_ros.core.gtfree import GroundTruthFree
from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.encoders import image_to_msg
from dispeval_ros.io.messages import disparity_from_msg, image_from_msg, stamp_ns
from dispeval_ros.offline.make_bag import GT_TOPIC, LEFT_IMAGE, RIGHT_IMAGE
from dispeval_ros.stream.core import CoreConfig, EvaluationCore

IMAGES = ["--left-image", LEFT_IMAGE, "--right-image", RIGHT_IMAGE]
GT_FREE_ROWS = ("gtfree:all", "gtfree:textured", "gtfree:textureless")


def run_bag(out: Path, *topics: str) -> dict[tuple[int, str], Any]:
    bag = sample_bag()
    methods = [a for n, t in sample_config(bag).methods.items() for a in ("--method", f"{n}={t}")]
    assert main(["bag", str(bag), *topics, *methods, "--out", str(out), "--quiet"]) == 0
    return stored_scores(out)


def direct_scores() -> dict[tuple[int, str], Any]:
    """Every frame's GT-free scores computed straight from the bag's decoded messages."""
    bag = sample_bag()
    config = sample_config(bag)
    free = GroundTruthFree()
    messages: dict[tuple[str, int], Any] = {}
    with BagSource(bag) as source:
        for topic, _, msg in source.messages([LEFT_IMAGE, RIGHT_IMAGE, *config.methods.values()]):
            messages[topic, stamp_ns(msg.header)] = msg
    expected = {}
    for (topic, stamp), msg in messages.items():
        if topic != LEFT_IMAGE:
            continue
        left = image_from_msg(msg).array
        right = image_from_msg(messages[RIGHT_IMAGE, stamp]).array
        pair = free.pair(left, right)
        for name, method_topic in config.methods.items():
            frame = disparity_from_msg(messages[method_topic, stamp])
            expected[stamp, name] = free.score(pair, frame.disparity, est_range=frame.est_range)
    return expected


def test_bag_scores_gt_free_rows_beside_unchanged_gt_rows(tmp_path: Path) -> None:
    plain = run_bag(tmp_path / "gt", "--gt", GT_TOPIC)
    both = run_bag(tmp_path / "both", "--gt", GT_TOPIC, *IMAGES)
    alone = run_bag(tmp_path / "alone", *IMAGES)
    expected = direct_scores()
    assert set(both) == set(plain)
    assert set(alone) == set(plain)  # without GT the left image is the frame clock
    for (stamp, method), scores in both.items():
        gt_rows = [scores.criteria.index(c) for c in plain[stamp, method].criteria]
        np.testing.assert_array_equal(scores.sums[gt_rows], plain[stamp, method].sums)
        direct = expected[stamp, method]
        free_rows = [scores.criteria.index(c) for c in GT_FREE_ROWS]
        np.testing.assert_array_equal(scores.sums[free_rows], direct.sums)
        np.testing.assert_array_equal(alone[stamp, method].sums, direct.sums)
        assert scores["gtfree:all"]["vpe"] == direct["gtfree:all"]["vpe"]
        assert 0 < scores["gtfree:all"]["vpe"] < 20
        assert math.isnan(scores["all"]["vpe"])


def stream_with_bad_images() -> tuple[list[tuple[str, Any]], list[int]]:
    """The sample's messages; frame 2 without right image, 4 with a colour right image, 6 with
    a left image of another size, 8 with a 16-bit left image."""
    bag = sample_bag()
    config = sample_config(bag)
    typestore = get_typestore(Stores.ROS2_JAZZY)
    topics = [*config.topics, LEFT_IMAGE, RIGHT_IMAGE]
    with BagSource(bag) as source:
        messages = [(topic, msg) for topic, _, msg in source.messages(topics)]
    stamps = sorted({stamp_ns(m.header) for t, m in messages if t == LEFT_IMAGE})
    replaced = {}
    for topic, msg in messages:
        stamp = stamp_ns(msg.header)
        array = image_from_msg(msg).array if topic in (LEFT_IMAGE, RIGHT_IMAGE) else None
        if topic == RIGHT_IMAGE and stamp == stamps[4]:
            replaced[topic, stamp] = image_to_msg(
                typestore, np.dstack([array] * 3), stamp, "stereo_right", "rgb8"
            )
        elif topic == LEFT_IMAGE and stamp == stamps[6]:
            replaced[topic, stamp] = image_to_msg(
                typestore, array[:-8], stamp, "stereo_left", "mono8"
            )
        elif topic == LEFT_IMAGE and stamp == stamps[8]:
            replaced[topic, stamp] = image_to_msg(
                typestore, array.astype(np.uint16), stamp, "stereo_left", "mono16"
            )
    stream = [
        (topic, replaced.get((topic, stamp_ns(msg.header)), msg))
        for topic, msg in messages
        if not (topic == RIGHT_IMAGE and stamp_ns(msg.header) == stamps[2])
    ]
    return stream, [stamps[i] for i in (2, 4, 6, 8)]


def test_bad_images_are_one_line_per_frame_and_never_fatal() -> None:
    stream, bad = stream_with_bad_images()
    config = sample_config(sample_bag())
    with_images = CoreConfig(
        **{**config.__dict__, "left_image_topic": LEFT_IMAGE, "right_image_topic": RIGHT_IMAGE}
    )
    core = EvaluationCore(with_images)
    results = []
    for topic, msg in stream:
        results += [core.score(frame_set) for frame_set in core.push(topic, msg)]
    results += [core.score(frame_set) for frame_set in core.flush()]
    assert len(results) == 25
    expected = direct_scores()
    problems = {}
    for result in results:
        assert set(result.scores) == set(config.methods), result.problems  # GT always scored
        left_stamp = result.stamp
        if left_stamp in bad:
            (problem,) = result.problems
            problems[left_stamp] = problem[1]
            for scores in result.scores.values():
                assert scores["gtfree:all"]["n"] == 0  # empty rows: sequences still add up
        else:
            assert result.problems == []
            for method, scores in result.scores.items():
                free_rows = [scores.criteria.index(c) for c in GT_FREE_ROWS]
                np.testing.assert_array_equal(
                    scores.sums[free_rows], expected[left_stamp, method].sums
                )
    assert "no image on /stereo/right/image_rect within 10 ms" in problems[bad[0]]
    assert (
        "is mono8 (grey) but the right image on /stereo/right/image_rect is rgb8"
        in (problems[bad[1]])
    )
    assert (
        f"images at {bad[2]}: the right image is 384×112 but the left image is 384×104; ground-truth-free"
        in problems[bad[2]]
    )
    assert "encoding 'mono16' is not an 8-bit grey or colour image" in problems[bad[3]]
    assert all(len(p.splitlines()) == 1 for p in problems.values())
    assert all(c.failed == 0 for c in core.counts().values())


def test_estimate_of_another_size_than_the_images_is_a_method_problem() -> None:
    config = sample_config(sample_bag())
    core = EvaluationCore(
        CoreConfig(
            methods=config.methods,
            gt_topic=LEFT_IMAGE,
            gt_kind="none",
            left_image_topic=LEFT_IMAGE,
            right_image_topic=RIGHT_IMAGE,
        )
    )
    typestore = get_typestore(Stores.ROS2_JAZZY)
    left = np.zeros((20, 30), np.uint8)
    stamp = 1_000_000_000
    core.push(LEFT_IMAGE, image_to_msg(typestore, left, stamp, "l", "mono8"))
    core.push(RIGHT_IMAGE, image_to_msg(typestore, left, stamp, "r", "mono8"))
    method, topic = next(iter(config.methods.items()))
    from dispeval_ros.io.encoders import disparity_to_msg

    disparity = disparity_to_msg(typestore, np.ones((20, 31), np.float32), stamp, "l", 1, 1, 0, 9)
    (frame_set,) = [*core.push(topic, disparity), *core.flush()]
    result = core.score(frame_set)
    assert result.scores == {}
    ((who, message),) = result.problems
    assert who == method
    assert message == (f"{topic} at {stamp}: the estimate is 31×20 but the images are 30×20")
    assert core.counts()[method].failed == 1


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (
            {"left_image_topic": LEFT_IMAGE},
            "give both the left image topic and the right image topic, or neither",
        ),
        ({"gt_kind": "none"}, "without ground truth the left image is the frame clock"),
        (
            {"left_image_topic": GT_TOPIC, "right_image_topic": RIGHT_IMAGE},
            "image, right-view and confidence topics must differ",
        ),
        ({"right_views": {"nobody": "/x"}}, "right-view disparity topics of unknown methods"),
    ],
)
def test_config_is_checked(options: dict[str, Any], message: str) -> None:
    from dispeval_ros.errors import ConfigurationError

    config = sample_config(sample_bag())
    with pytest.raises(ConfigurationError, match=message):
        CoreConfig(**{**config.__dict__, **options})


def test_roi_is_not_a_stream_criterion() -> None:
    from dispeval_ros.errors import ConfigurationError

    config = sample_config(sample_bag())
    with pytest.raises(ConfigurationError, match="'roi' needs a mask"):
        CoreConfig(
            **{
                **config.__dict__,
                "left_image_topic": LEFT_IMAGE,
                "right_image_topic": RIGHT_IMAGE,
                "gt_free_criteria": ("all", "roi"),
            }
        )
