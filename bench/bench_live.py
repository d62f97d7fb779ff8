"""The live node core alone: three methods at 1242×375 fed at 30 Hz on one core.

    python bench/bench_live.py [--seconds 10] [--rate 30]

Real DisparityImage / Image / CameraInfo message objects (rosbags' ROS 2 Humble types) are
pushed at the given rate from a feeder thread, each method's estimate a few milliseconds after
its images, as a stereo pipeline publishes them. Reports the sustained rate, drops, and the
latency from the arrival of a frame's last message to its scores being emitted (p50/p99),
next to the per-frame scoring cost measured in the same run. Asserts nothing.
"""

from __future__ import annotations

import argparse
import os
import statistics
import threading
import time

import numpy as np
from rosbags.typesys import Stores, get_typestore

from dispeval_ros.io.encoders import camera_info_to_msg, disparity_to_msg, image_to_msg
from dispeval_ros.offline.make_bag import GT_TOPIC, LEFT_INFO, RIGHT_INFO, disparity_topic
from dispeval_ros.stream.core import CoreConfig, EvaluationCore, FrameResult
from dispeval_ros.stream.runner import LiveEvaluator
from dispeval_ros.testbed import default_methods, make_driving_sequence

METHODS = ("bm_fast", "sgbm", "sgbm_3way")


def frame_messages(n_frames: int) -> list[list[tuple[str, object, int]]]:
    """Per frame: (topic, message, delay after the frame's start in ns), rendered once."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    methods = [m for m in default_methods(1242) if m.name in METHODS]
    frames = []
    for frame in make_driving_sequence(n_frames, 1242, 375, fps=30.0, seed=11):
        stamp = 1_700_000_000_000_000_000 + round(frame.stamp * 1e9)
        camera = frame.camera
        messages: list[tuple[str, object, int]] = [
            (LEFT_INFO, camera_info_to_msg(store, camera, 1242, 375, stamp, "l", False), 0),
            (RIGHT_INFO, camera_info_to_msg(store, camera, 1242, 375, stamp, "r", True), 0),
            (GT_TOPIC, image_to_msg(store, frame.gt_left, stamp, "l", "32FC1"), 0),
        ]
        for index, method in enumerate(methods):
            disparity = method.compute(frame.left, frame.right)
            msg = disparity_to_msg(
                store,
                disparity,
                stamp,
                "l",
                camera.f,
                camera.baseline,
                method.min_disparity,
                method.max_disparity,
            )
            messages.append((disparity_topic(method.name), msg, (2 + 3 * index) * 1_000_000))
        frames.append(messages)
    return frames


def main() -> None:
    """Feed at the rate for the duration; report."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--rate", type=float, default=30.0)
    parser.add_argument(
        "--distinct", type=int, default=30, help="distinct frames rendered (then reused)"
    )
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    config = CoreConfig(
        methods={m: disparity_topic(m) for m in METHODS},
        gt_topic=GT_TOPIC,
        left_info_topic=LEFT_INFO,
        right_info_topic=RIGHT_INFO,
    )
    print(
        f"rendering {args.distinct} frames of 1242×375 and running {len(METHODS)} OpenCV methods on them…"
    )
    frames = frame_messages(args.distinct)

    core = EvaluationCore(config)  # the per-frame cost, measured here as the baseline
    costs = []
    for messages in frames:
        ready = []
        for topic, msg, _ in messages:
            ready += core.push(topic, msg)
        for frame_set in ready:
            started = time.perf_counter()
            core.score(frame_set)
            costs.append(time.perf_counter() - started)
    per_frame = statistics.median(costs[1:]) * 1e3

    results: list[FrameResult] = []
    live = LiveEvaluator(config, results.append, queue_size=4)
    period = 1.0 / args.rate
    total = round(args.seconds * args.rate)
    started = time.perf_counter()

    def feed() -> None:
        for i in range(total):
            tick = started + i * period
            messages = frames[i % len(frames)]
            shift = (i // len(frames)) * len(frames) * round(period * 1e9)
            for topic, msg, delay in messages:
                due = tick + delay / 1e9
                wait = due - time.perf_counter()
                if wait > 0:
                    time.sleep(wait)
                live.push(topic, _shifted(msg, shift))

    feeder = threading.Thread(target=feed)
    feeder.start()
    feeder.join()
    fed_seconds = time.perf_counter() - started
    live.stop(flush=True)
    latencies = np.array(live.stats.latencies) * 1e3
    counts = live.counts()
    dropped = sum(c.dropped for c in counts.values())
    print(
        f"\nscoring one frame set (GT partition + {len(METHODS)} methods), median: {per_frame:.1f} ms "
        f"→ at most {1000 / per_frame:.0f} Hz on one core"
    )
    print(
        f"fed {total} frame sets at {args.rate:g} Hz ({total / fed_seconds:.1f} Hz achieved by the feeder)"
    )
    print(
        f"scored {len(results)} frame sets; dropped method-frames: {dropped}; "
        f"queue drops: {live.stats.queue_drops}"
    )
    print(
        f"latency, last message → scores emitted: p50 {np.percentile(latencies, 50):.1f} ms, "
        f"p99 {np.percentile(latencies, 99):.1f} ms, max {latencies.max():.1f} ms"
    )


def _shifted(msg: object, shift: int) -> object:
    """The message with its header stamp moved by ``shift`` ns (frames are reused on a loop)."""
    if shift == 0:
        return msg
    import dataclasses

    header = msg.header  # type: ignore[attr-defined]
    stamp = header.stamp.sec * 10**9 + header.stamp.nanosec + shift
    new_stamp = dataclasses.replace(header.stamp, sec=stamp // 10**9, nanosec=stamp % 10**9)
    return dataclasses.replace(msg, header=dataclasses.replace(header, stamp=new_stamp))  # type: ignore[type-var]


if __name__ == "__main__":
    main()
