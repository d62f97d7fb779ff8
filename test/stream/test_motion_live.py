"""Live ego-motion pairs wait a moment for /tf that lags the frame (odometry is often published
a few ms after the image), and never for /tf that has stopped."""

from __future__ import annotations

import queue
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from bag_support import noisy_drive_bag

from dispeval_ros.io.bags import BagSource
from dispeval_ros.offline.make_bag import (
    GT_TOPIC,
    LEFT_IMAGE,
    LEFT_INFO,
    RIGHT_IMAGE,
    RIGHT_INFO,
    TF_TOPIC,
    disparity_topic,
    synthetic_frames,
)
from dispeval_ros.stream import runner
from dispeval_ros.stream.core import CoreConfig, FrameResult
from dispeval_ros.stream.runner import LiveEvaluator

NOISE = {"truth": 0.0, "noisy": 0.5}
FRAMES = 5


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    drive = list(synthetic_frames(FRAMES, 320, 96, 10.0, seed=4))
    return noisy_drive_bag(tmp_path_factory.mktemp("late_tf"), drive, NOISE, seed=5)


def run_live(
    bag: Path, tf_held: bool, tf_stops: bool = False
) -> tuple[list[FrameResult], LiveEvaluator]:
    """The bag fed live, a frame every 20 ms. ``tf_held``: the /tf at frame k is delivered only
    once the pair ending at k waits for it (so it is late, whatever the machine's speed), or
    after 1 s; ``tf_stops``: no /tf after the first frame's."""
    config = CoreConfig(
        methods={m: disparity_topic(m) for m in NOISE},
        gt_topic=GT_TOPIC,
        left_info_topic=LEFT_INFO,
        right_info_topic=RIGHT_INFO,
        left_image_topic=LEFT_IMAGE,
        right_image_topic=RIGHT_IMAGE,
        egomotion=True,
    )
    results: list[FrameResult] = []
    live = LiveEvaluator(config, results.append, queue_size=100)
    transforms: queue.Queue[tuple[str, Any, int] | None] = queue.Queue()

    def deliver() -> None:
        index = 0
        while (item := transforms.get()) is not None:
            deadline = time.monotonic() + 1.0
            while tf_held and index and live.stats.motion_waits < index:
                if time.monotonic() > deadline:
                    break
                time.sleep(0.001)
            live.push(*item[:2], received=item[2])
            index += 1

    courier = threading.Thread(target=deliver)
    courier.start()
    sent = 0
    with BagSource(bag) as source:
        for topic, log_ns, msg in source.messages(list(config.topics)):
            if topic == TF_TOPIC:
                if not (tf_stops and sent):
                    transforms.put((topic, msg, log_ns))
                sent += 1
                continue
            live.push(topic, msg, received=log_ns)
            if topic == GT_TOPIC:
                time.sleep(0.02)
    transforms.put(None)
    courier.join()
    live.stop(flush=True)
    return results, live


def motion_problems(results: list[FrameResult]) -> list[str]:
    return [text for r in results for _, text in r.problems if "no ego-motion pair" in text]


def test_pairs_wait_for_tf_that_lags_the_frame(bag: Path) -> None:
    results, live = run_live(bag, tf_held=True)
    assert len(results) == FRAMES
    assert not motion_problems(results)
    assert [len(r.motion_pairs) for r in results] == [0] + [len(NOISE)] * (FRAMES - 1)
    assert live.stats.motion_waits == FRAMES - 1  # every pair waited for its later /tf


def test_without_the_grace_the_same_feed_loses_its_pairs(
    bag: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(runner, "LIVE_MOTION_GRACE_S", 0.0)
    results, _ = run_live(bag, tf_held=True)
    assert motion_problems(results)


def test_tf_that_stopped_is_not_waited_for(bag: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """/tf ends after the first frame: the later frames are 0.1–0.4 s ahead of it, stale here."""
    monkeypatch.setattr(runner, "LIVE_MOTION_STALE_NS", 50_000_000)
    results, live = run_live(bag, tf_held=False, tf_stops=True)
    assert len(results) == FRAMES
    assert live.stats.motion_waits == 0
    assert len(motion_problems(results)) == FRAMES - 1  # one line per pair, as before
