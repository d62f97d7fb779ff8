"""End-to-end offline speed: read + decode + join + score + store, in matched method-frames/s.

    python bench/bench_bag.py [--frames 60] [--storage rosbag2-mcap] [--bag PATH] [--rounds 3]

Writes a synthetic 1242×375 drive with three methods (bm_fast, sgbm, sgbm_3way), then times
the reader alone (the baseline: iterate and deserialize every message), one pass that reads,
joins and scores without units or store (what the pipeline adds is measured against it),
`dispeval bag` in one process, and with --jobs 2, each the best of --rounds. Prints rates and
ratios; asserts nothing (machines are noisy).
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.bag_eval import evaluate_bags
from dispeval_ros.offline.make_bag import (
    GT_TOPIC,
    bag_config,
    synthetic_frames,
    write_bag,
)
from dispeval_ros.stream.core import EvaluationCore
from dispeval_ros.testbed import default_methods

METHODS = ("bm_fast", "sgbm", "sgbm_3way")


def main() -> None:
    """Write the bag, then time reading alone and the whole pipeline."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--storage", default="rosbag2-mcap")
    parser.add_argument("--bag", type=Path, help="reuse a bag this benchmark wrote before")
    parser.add_argument("--rounds", type=int, default=3, help="best of this many runs of each")
    args = parser.parse_args()
    root = Path(tempfile.mkdtemp(prefix="dispeval-bench-"))
    bag = args.bag or root / "drive"
    if args.bag is None:
        methods = [m for m in default_methods(1242) if m.name in METHODS]
        started = time.perf_counter()
        write_bag(
            bag,
            synthetic_frames(args.frames, 1242, 375, 10.0, seed=5),
            storage=args.storage,
            methods=methods,
        )
        print(
            f"wrote {args.frames} frames of 1242×375 ({args.storage}) "
            f"in {time.perf_counter() - started:.1f} s: {bag}"
        )
    config = bag_config(METHODS)
    read_seconds = math.inf
    for _ in range(args.rounds):
        started = time.perf_counter()
        count = gts = 0
        with BagSource(bag) as source:
            for topic, _, _ in source.messages(list(config.topics)):
                count += 1
                gts += topic == GT_TOPIC
        read_seconds = min(read_seconds, time.perf_counter() - started)
    method_frames = gts * len(METHODS)
    print(
        f"\nreader alone: {count} messages in {read_seconds:.2f} s: "
        f"{method_frames / read_seconds:7.1f} method-frames/s (baseline)"
    )
    with ResultsStore.create(root / "warm-up", {}) as store:  # compile (or load) the kernels first
        evaluate_bags([bag], config, store)
    # the floor of the pipeline: one pass that reads, joins and scores, without units or store
    pass_seconds = math.inf
    for _ in range(args.rounds):
        started = time.perf_counter()
        core = EvaluationCore(config)
        with BagSource(bag) as source:
            for topic, _, msg in source.messages(list(config.topics)):
                for frame_set in core.push(topic, msg):
                    core.score(frame_set)
        for frame_set in core.flush():
            core.score(frame_set)
        pass_seconds = min(pass_seconds, time.perf_counter() - started)
    print(
        f"read + join + score in one pass (no units, no store): {pass_seconds:.2f} s: "
        f"{method_frames / pass_seconds:7.1f} method-frames/s "
        f"({read_seconds / pass_seconds:.2f}× the reader alone)"
    )
    for jobs in (1, 2):
        seconds = math.inf
        for round_ in range(args.rounds):
            out = root / f"out{jobs}-{round_}"
            started = time.perf_counter()
            with ResultsStore.create(out, {"jobs": jobs}) as store:
                report = evaluate_bags([bag], config, store, jobs=jobs)
            seconds = min(seconds, time.perf_counter() - started)
        rate = report.frames / seconds
        print(
            f"dispeval bag, --jobs {jobs}: {report.frames} matched method-frames in {seconds:.2f} s: "
            f"{rate:7.1f} method-frames/s ({rate / (method_frames / read_seconds):.2f}× the reader "
            f"alone, {pass_seconds / seconds:.2f}× the one pass)"
        )


if __name__ == "__main__":
    main()
