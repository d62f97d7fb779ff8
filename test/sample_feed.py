"""The sample bag as a robot would deliver it, and what ``dispeval bag`` makes of it.

Shared by the tests of every live front end (the transport-free core, the rclpy nodes): the
same perturbed feed (a jittery clock, dropped frames, reordering) must give the same scores as
``dispeval bag`` on the recording, and exactly the expected counts.
"""

from __future__ import annotations

import dataclasses
import os
import random
import subprocess
import sys
from pathlib import Path
from typing import Any

from dispeval_ros.cli.main import main
from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.messages import stamp_ns
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import GT_TOPIC, LEFT_INFO, RIGHT_INFO
from dispeval_ros.offline.sample import find_sample_bag
from dispeval_ros.stream.core import CoreConfig, MethodCounts

MS = 1_000_000

Stream = list[tuple[str, int, Any]]
"""(topic, log time in ns, message) in delivery order."""


def sample_bag() -> Path:
    bag = find_sample_bag()
    assert bag is not None, "bags/sample_drive is part of the repository"
    return bag


def sample_config(bag: Path) -> CoreConfig:
    with BagSource(bag) as source:
        methods = {
            t.split("/")[2]: t
            for t, i in source.topics.items()
            if i.msgtype == "stereo_msgs/msg/DisparityImage"
        }
    return CoreConfig(
        methods=methods, gt_topic=GT_TOPIC, left_info_topic=LEFT_INFO, right_info_topic=RIGHT_INFO
    )


def topic_args(config: CoreConfig) -> list[str]:
    """``--gt``, ``--camera-info`` and one ``--method`` per method, as the stream commands take."""
    args = ["--gt", config.gt_topic]
    if config.left_info_topic and config.right_info_topic:
        args += ["--camera-info", config.left_info_topic, config.right_info_topic]
    for name, topic in config.methods.items():
        args += ["--method", f"{name}={topic}"]
    return args


def bag_reference(bag: Path, out: Path) -> dict[tuple[int, str], Any]:
    """What ``dispeval bag`` stores for ``bag``: (GT stamp, method) → Scores."""
    args = ["bag", str(bag), *topic_args(sample_config(bag)), "--out", str(out), "--quiet"]
    assert main(args) == 0
    return stored_scores(out, problems_allowed=True)


def stored_scores(out: Path, problems_allowed: bool = False) -> dict[tuple[int, str], Any]:
    """A one-sequence results folder's frames: (stamp, method) → Scores."""
    with ResultsStore.open(out) as store:
        (sequence,) = store.sequences()
        assert problems_allowed or store.problems() == []
        return {
            (stamp, method): scores
            for stamp in store.stamps(sequence)
            for method, scores in store.frame_scores(sequence, stamp).items()
        }


def dispeval_process(*args: str, log: Path) -> subprocess.Popen[bytes]:
    """A ``dispeval`` command as its own process (its own DDS participant), output to ``log``."""
    env = {k: v for k, v in os.environ.items() if k not in ("CYCLONEDDS_URI", "ROS_DOMAIN_ID")}
    with log.open("wb") as stream:
        return subprocess.Popen(
            [sys.executable, "-m", "dispeval_ros", *args],
            stdout=stream,
            stderr=subprocess.STDOUT,
            env=env,
        )


def restamped(msg: Any, delta: int) -> Any:
    """A copy of a message whose header stamp moved by ``delta`` ns (real rosbags objects)."""
    stamp = stamp_ns(msg.header) + delta
    header = dataclasses.replace(
        msg.header,
        stamp=dataclasses.replace(msg.header.stamp, sec=stamp // 10**9, nanosec=stamp % 10**9),
    )
    return dataclasses.replace(msg, header=header)


def robot_stream(bag: Path, config: CoreConfig, seed: int = 3) -> tuple[Stream, dict[str, Any]]:
    """The bag's messages with stamp jitter, a few dropped frames and a little reordering."""
    rng = random.Random(seed)
    with BagSource(bag) as source:
        messages = list(source.messages(list(config.topics)))
    gt_stamps = sorted(stamp_ns(m.header) for t, _, m in messages if t == GT_TOPIC)
    methods = list(config.methods)
    dropped_gt = {gt_stamps[5], gt_stamps[17]}
    dropped_estimates = {
        (methods[0], gt_stamps[3]),
        (methods[1], gt_stamps[3]),
        (methods[-1], gt_stamps[11]),
    }
    stream: Stream = []
    for topic, log_time, original in messages:
        msg = original
        stamp = stamp_ns(msg.header)
        if topic == GT_TOPIC and stamp in dropped_gt:
            continue
        method = next((m for m, t in config.methods.items() if t == topic), None)
        if method is not None:
            if (method, stamp) in dropped_estimates:
                continue
            if method == methods[1]:  # a driver with a jittery clock: ±4 ms (tolerance 10 ms)
                msg = restamped(msg, rng.randint(-4, 4) * MS)
        stream.append((topic, log_time, msg))
    for i in range(0, len(stream) - 1, 7):  # transport reordering between topics
        stream[i], stream[i + 1] = stream[i + 1], stream[i]
    expected = {
        "dropped_gt": dropped_gt,
        "dropped_estimates": dropped_estimates,
        "gt_stamps": gt_stamps,
    }
    return stream, expected


def expected_counts(config: CoreConfig, expected: dict[str, Any]) -> dict[str, MethodCounts]:
    """Per method: what the feed of :func:`robot_stream` must give."""
    counts = {}
    n_gt = len(expected["gt_stamps"])
    for method in config.methods:
        own_drops = sum(1 for m, _ in expected["dropped_estimates"] if m == method)
        # its estimates of the two dropped GT frames have nothing to pair with
        unmatched = len(expected["dropped_gt"])
        counts[method] = MethodCounts(n_gt - unmatched - own_drops, unmatched, own_drops, 0)
    return counts
