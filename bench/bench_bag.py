"""End-to-end offline speed: read + decode + join + score + store, in matched method-frames/s.

    python bench/bench_bag.py [--frames 60] [--storage rosbag2-mcap] [--bag PATH] [--rounds 3]

Writes a synthetic 1242×375 drive with three methods (bm_fast, sgbm, sgbm_3way), or reuses
--bag. First the cost of each stage on its own (per frame or per method-frame, in one thread):
opening the bag, reading and deserialising, decoding the pixel buffers, joining, the partition
of each ground-truth map, scoring, building the unit rows and storing them, and hashing the
scored streams for the provenance record; their sum is what one thread needs per frame,
against what 0.5× the reader alone allows. Then the reader alone (the baseline, the floor:
rosbags' ``AnyReader`` opening the bag, iterating and deserialising every message with its own
deserialiser), the project's reader (``BagSource``) doing the same, one pass that reads, joins
and scores in one thread without units, store or provenance, the pipeline (`evaluate_bags`:
units, store) and the whole `dispeval bag` command (run in this process, kernels loaded: the
pipeline plus the provenance digests, the CSV export and the summary), each with --jobs 1 and
2, and last the CPU time of each thread of a pipeline and a command run with --jobs 1 (how
many cores they keep busy). Each is the best of --rounds, the rounds interleaved (the machine
is shared: the load average is printed, and --idle-cores N waits, up to a minute, for N idle
cores before each timed run of the pipeline). Asserts nothing (machines are noisy).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import os
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import dispeval_ros
from dispeval_ros.cli.main import main as dispeval
from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.messages import disparity_from_msg, gt_disparity, image_from_msg
from dispeval_ros.io.store import FrameScores, ResultsStore, prepare_unit
from dispeval_ros.offline.bag_eval import evaluate_bags
from dispeval_ros.offline.make_bag import (
    GT_TOPIC,
    LEFT_INFO,
    RIGHT_INFO,
    bag_config,
    synthetic_frames,
    write_bag,
)
from dispeval_ros.offline.memory import keep_frames_on_the_heap
from dispeval_ros.stream.core import CoreConfig, EvaluationCore
from dispeval_ros.testbed import default_methods

try:  # absent before 2026-11 (this bench also times older versions: PYTHONPATH=old/checkout)
    from dispeval_ros.offline.records import BagStreams
except ImportError:  # pragma: no cover
    BagStreams = None  # type: ignore[assignment,misc]
try:  # absent before 2026-12: the stream digests were sha256 only
    from dispeval_ros.io.provenance import digests_to_damage, stream_algorithm
    from dispeval_ros.offline.records import stream_topics
except ImportError:  # pragma: no cover
    stream_algorithm = None  # type: ignore[assignment]

METHODS = ("bm_fast", "sgbm", "sgbm_3way")
STAGE_FRAMES = 20
"""Frames held in memory to time the stages after reading (each holds ~7.5 MB of messages)."""
SHA256_BEFORE = "(stream digests with sha256)"
"""The stage cost of the digests as they were before BLAKE3: printed, not counted."""


def write_drive(bag: Path, frames: int, storage: str) -> Path:
    """The bench's bag: a synthetic 1242×375 drive with the three methods (as make-bag)."""
    methods = [m for m in default_methods(1242) if m.name in METHODS]
    started = time.perf_counter()
    write_bag(
        bag, synthetic_frames(frames, 1242, 375, 10.0, seed=5), storage=storage, methods=methods
    )
    print(
        f"wrote {frames} frames of 1242×375 ({storage}) "
        f"in {time.perf_counter() - started:.1f} s: {bag}"
    )
    return bag


def warm_up(bag: Path, config: CoreConfig, root: Path) -> None:
    """Compile (or load) the kernels: one pipeline run before anything is timed."""
    with ResultsStore.create(root / "warm-up", {}) as store:
        evaluate_bags([bag], config, store)


def best(rounds: int, run: Callable[[], Any]) -> float:
    """The shortest of ``rounds`` runs, in seconds."""
    seconds = math.inf
    for _ in range(rounds):
        started = time.perf_counter()
        run()
        seconds = min(seconds, time.perf_counter() - started)
    return seconds


def idle_cores(seconds: float = 1.0) -> float | None:
    """Cores left idle over ``seconds`` (from /proc/stat; None where there is none)."""

    def sample() -> tuple[int, int]:
        with open("/proc/stat", encoding="ascii") as stat:
            ticks = [int(value) for value in stat.readline().split()[1:]]
        return ticks[3] + ticks[4], sum(ticks)  # idle + iowait, all

    try:
        idle, total = sample()
        time.sleep(seconds)
        idle_after, total_after = sample()
    except OSError:
        return None
    return (os.cpu_count() or 1) * (idle_after - idle) / max(1, total_after - total)


def wait_for_idle(cores: float, patience: float = 60.0) -> None:
    """Wait until ``cores`` cores are idle (or ``patience`` seconds have passed)."""
    deadline = time.perf_counter() + patience
    while cores > 0 and time.perf_counter() < deadline:
        idle = idle_cores()
        if idle is None or idle >= cores:
            return


def rosbags_opens(bag: Path) -> bool:
    """Whether rosbags' ``AnyReader`` opens the bag (not plain MCAP files)."""
    return not (bag.is_file() and bag.suffix == ".mcap")


def rosbags_read(reader: Any, config: CoreConfig, stop: int | None = None) -> int:
    """Iterate and deserialise the configured topics with rosbags; the GT frames read.

    rosbags' own CDR deserialiser, not the project's reader; the first ``stop`` messages only
    when given.
    """
    connections = [c for c in reader.connections if c.topic in config.topics]
    gts = 0
    for index, (connection, _, raw) in enumerate(reader.messages(connections)):
        reader.deserialize(raw, connection.msgtype)
        gts += connection.topic == GT_TOPIC
        if index + 1 == stop:
            break
    return gts


def rosbags_floor(bag: Path, config: CoreConfig) -> int | None:
    """rosbags alone (the floor): open, iterate and deserialise every message; the GT frames.

    None for a bag rosbags cannot open.
    """
    from rosbags.highlevel import AnyReader

    if not rosbags_opens(bag):
        return None
    with AnyReader([bag]) as reader:
        return rosbags_read(reader, config)


def read_all(bag: Path, config: CoreConfig) -> int:
    """The project's reader alone (``BagSource``): open, iterate and deserialise every message."""
    gts = 0
    with BagSource(bag) as source:
        for topic, _, _ in source.messages(list(config.topics)):
            gts += topic == GT_TOPIC
    return gts


def one_pass(bag: Path, config: CoreConfig) -> None:
    """Read, join and score in one thread, without units or store."""
    core = EvaluationCore(config)
    with BagSource(bag) as source:
        for topic, _, msg in source.messages(list(config.topics)):
            for frame_set in core.push(topic, msg):
                core.score(frame_set)
    for frame_set in core.flush():
        core.score(frame_set)


def pipeline_run(bag: Path, config: CoreConfig, out: Path, jobs: int = 1) -> None:
    """``evaluate_bags`` of the bench's bag into a new results database at ``out``."""
    with ResultsStore.create(out, {"jobs": jobs}) as store:
        evaluate_bags([bag], config, store, jobs=jobs)


def bag_command(bag: Path, out: Path, jobs: int) -> int:
    """``dispeval bag`` on the bench's bag, its output muted; the matched method-frames."""
    config = bag_config(METHODS)
    argv = ["bag", str(bag), "--gt", GT_TOPIC, "--camera-info", LEFT_INFO, RIGHT_INFO]
    argv += [arg for item in config.methods.items() for arg in ("--method", "=".join(item))]
    argv += ["--out", str(out), "--jobs", str(jobs), "--quiet", "--json"]
    with contextlib.redirect_stdout(io.StringIO()):
        if dispeval(argv) != 0:
            raise SystemExit(f"dispeval bag failed: {' '.join(argv)}")
    with ResultsStore.open(out) as store:
        sequence = store.sequences()[0]
        return sum(counts.matched for counts in store.match_counts(sequence).values())


def stage_costs(bag: Path, config: CoreConfig, rounds: int) -> dict[str, tuple[float, str]]:
    """Each stage on its own, in this thread: name → (milliseconds, per what)."""
    opened = best(rounds, lambda: BagSource(bag).close())
    source = BagSource(bag)
    messages: list[tuple[str, Any]] = []
    for topic, _, msg in source.messages(list(config.topics)):
        if topic == GT_TOPIC and sum(t == GT_TOPIC for t, _ in messages) == STAGE_FRAMES:
            break
        messages.append((topic, msg))
    gts = sum(topic == GT_TOPIC for topic, _ in messages)
    frames = min(gts, STAGE_FRAMES)
    stop = len(messages)

    def read() -> None:
        for index, _ in enumerate(source.messages(list(config.topics))):
            if index + 1 == stop:
                break

    reading = best(rounds, read)
    source.close()
    floor_reading = rosbags_stage(bag, config, stop, rounds)
    core = EvaluationCore(config)
    frame_sets = [fs for topic, msg in messages for fs in core.push(topic, msg)]
    frame_sets += core.flush()
    frame_sets = frame_sets[:frames]
    method_frames = sum(len(fs.estimates) for fs in frame_sets)

    def join() -> None:
        joiner = EvaluationCore(config)
        for topic, msg in messages:
            joiner.push(topic, msg)
        joiner.flush()

    def decode_frame(fs: Any) -> tuple[Any, Any, list[Any]]:
        estimates = [disparity_from_msg(msg) for _, msg in fs.estimates.values()]
        camera = core.camera(estimates[0].camera)
        return gt_disparity(image_from_msg(fs.gt), "disparity", None, camera), camera, estimates

    def decode() -> None:
        for fs in frame_sets:  # each frame's arrays freed before the next, as in the pipeline
            decode_frame(fs)

    decoded = [decode_frame(fs) for fs in frame_sets]
    evaluator = core.evaluator
    references = [evaluator.reference(gt, camera) for gt, camera, _ in decoded]

    def partition() -> None:
        for gt, camera, _ in decoded:
            evaluator.reference(gt, camera)

    def score() -> list[FrameScores]:
        return [
            FrameScores(
                "bench", fs.stamp, method, evaluator.score(ref, e.disparity, est_range=e.est_range)
            )
            for fs, ref, (_, _, estimates) in zip(frame_sets, references, decoded, strict=True)
            for method, e in zip(fs.estimates, estimates, strict=True)
        ]

    rows = score()
    root = Path(tempfile.mkdtemp(prefix="dispeval-bench-store-"))
    stores = iter(range(rounds))

    def store() -> None:
        with ResultsStore.create(root / f"s{next(stores)}", {}) as results:
            results.add_prepared(prepare_unit("bench", "000000", rows))

    ms = 1e3
    costs = {
        "open the bag": (opened * ms, "per bag"),
        "read + deserialise (rosbags)": (floor_reading / frames * ms, "per frame"),
        "read + deserialise (ours)": (reading / frames * ms, "per frame"),
        "decode pixels (estimates, GT)": (best(rounds, decode) / frames * ms, "per frame"),
        "join": (best(rounds, join) / frames * ms, "per frame"),
        "partition": (best(rounds, partition) / frames * ms, "per frame"),
        "score": (best(rounds, score) / method_frames * ms, "per method-frame"),
        "unit rows + store": (best(rounds, store) / method_frames * ms, "per method-frame"),
    }
    if BagStreams is not None:
        digests = best(rounds, BagStreams([bag], config).compute)
        label = f"stream digests ({stream_algorithm()})" if stream_algorithm else "stream digests"
        costs[label] = (digests / gts_in_bag(bag) * ms, "per frame")
    if stream_algorithm is not None and stream_algorithm() != "sha256":  # what they cost before
        topics = stream_topics(config)
        with BagSource(bag) as opened:
            sha256 = best(rounds, lambda: digests_to_damage(bag, topics, opened, "sha256"))
        costs[SHA256_BEFORE] = (sha256 / gts_in_bag(bag) * ms, "per frame")
    return costs


def rosbags_stage(bag: Path, config: CoreConfig, stop: int, rounds: int) -> float:
    """rosbags reading and deserialising the first ``stop`` messages (the bag open), seconds.

    NaN where rosbags cannot open the bag (plain MCAP files).
    """
    from rosbags.highlevel import AnyReader

    if not rosbags_opens(bag):
        return math.nan
    with AnyReader([bag]) as reader:
        return best(rounds, lambda: rosbags_read(reader, config, stop))


def gts_in_bag(bag: Path) -> int:
    """Ground-truth frames in the bag."""
    with BagSource(bag) as source:
        return source.topics[GT_TOPIC].count


def cpu_per_thread(run: Callable[[], Any]) -> tuple[float, dict[str, float]]:
    """Wall seconds of ``run()`` and CPU seconds per thread name (from /proc; Linux only).

    A sampler reads every thread's CPU time every 20 ms, so threads that end during the run
    are counted up to their last sample. Empty where /proc/self/task is missing.
    """
    if not Path("/proc/self/task").is_dir():
        started = time.perf_counter()
        run()
        return time.perf_counter() - started, {}
    tick = os.sysconf("SC_CLK_TCK")
    seen: dict[int, tuple[str, float]] = {}

    def sample() -> dict[int, tuple[str, float]]:
        names = {t.native_id: t.name.rstrip("0123456789_-") for t in threading.enumerate()}
        found = {}
        for task in os.listdir("/proc/self/task"):
            with contextlib.suppress(OSError, IndexError, ValueError):
                with open(f"/proc/self/task/{task}/stat", encoding="ascii") as stat:
                    fields = stat.read().rsplit(")", 1)[1].split()
                native = int(task)
                found[native] = (names.get(native, "?"), (int(fields[11]) + int(fields[12])) / tick)
        return found

    before = sample()
    done = threading.Event()

    def sampler() -> None:
        while not done.is_set():
            seen.update(sample())
            time.sleep(0.02)

    thread = threading.Thread(target=sampler, name="bench-sampler", daemon=True)
    thread.start()
    started = time.perf_counter()
    run()
    wall = time.perf_counter() - started
    done.set()
    thread.join()
    seen.update(sample())
    cpu: dict[str, float] = {}
    for native, (name, seconds) in seen.items():
        if name != "bench-sampler":
            cpu[name] = cpu.get(name, 0.0) + seconds - before.get(native, (name, 0.0))[1]
    return wall, {name: seconds for name, seconds in cpu.items() if seconds > 0.005}


def main() -> None:
    """Write the bag, time each stage, then reading alone and the whole pipeline."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--storage", default="rosbag2-mcap")
    parser.add_argument("--bag", type=Path, help="reuse a bag this benchmark wrote before")
    parser.add_argument("--rounds", type=int, default=3, help="best of this many runs of each")
    parser.add_argument(
        "--idle-cores",
        type=float,
        default=0.0,
        help="before each timed pipeline run, wait (up to 60 s) for this many idle cores",
    )
    args = parser.parse_args()
    keep_frames_on_the_heap()  # as the pipeline does
    root = Path(tempfile.mkdtemp(prefix="dispeval-bench-"))
    bag = args.bag or write_drive(root / "drive", args.frames, args.storage)
    config = bag_config(METHODS)
    warm_up(bag, config, root)
    load = " ".join(f"{value:.2f}" for value in os.getloadavg())
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(f"{dispeval_ros.__file__}: {cores} cores, load average {load}")

    costs = stage_costs(bag, config, args.rounds)
    print(f"\nstage costs, one thread (best of {args.rounds}, first {STAGE_FRAMES} frames):")
    for name, (value, per) in costs.items():
        print(f"  {name:32s} {value:7.2f} ms {per}")
    methods = len(METHODS)
    costs.pop(SHA256_BEFORE, None)
    floor = costs.pop("read + deserialise (rosbags)")[0]
    per_frame = sum(v * (methods if p == "per method-frame" else 1) for v, p in costs.values())
    per_frame -= costs["open the bag"][0]
    reading = floor if math.isfinite(floor) else costs["read + deserialise (ours)"][0]
    print(
        f"  one thread needs {per_frame:.1f} ms per frame (+ the open); 0.5× the reader alone "
        f"allows {2 * reading:.1f} ms per frame (+ the open)"
    )

    reader = ours = one = math.inf
    pipeline = {1: math.inf, 2: math.inf}
    command = {1: math.inf, 2: math.inf}
    frames = {1: 0, 2: 0}
    gts = 0
    for round_ in range(args.rounds):  # interleaved: a busy moment hurts every line alike
        wait_for_idle(args.idle_cores)
        started = time.perf_counter()
        floor_gts = rosbags_floor(bag, config)
        reader = min(reader, time.perf_counter() - started)
        wait_for_idle(args.idle_cores)
        started = time.perf_counter()
        gts = read_all(bag, config)
        ours = min(ours, time.perf_counter() - started)
        if floor_gts is None:  # rosbags cannot open it: our reader is the floor
            reader = ours
        one = min(one, best(1, lambda: one_pass(bag, config)))
        for jobs, seconds in pipeline.items():
            wait_for_idle(args.idle_cores)
            started = time.perf_counter()
            pipeline_run(bag, config, root / f"run{jobs}-{round_}", jobs)
            pipeline[jobs] = min(seconds, time.perf_counter() - started)
            wait_for_idle(args.idle_cores)
            started = time.perf_counter()
            frames[jobs] = bag_command(bag, root / f"out{jobs}-{round_}", jobs)
            command[jobs] = min(command[jobs], time.perf_counter() - started)
    method_frames = gts * methods
    floor = method_frames / reader
    print(
        f"\nreader alone (rosbags AnyReader + its deserialiser): {gts} frames in {reader:.2f} s: "
        f"{floor:7.1f} method-frames/s (baseline, the floor)"
    )
    print(
        f"our reader alone (BagSource): {ours:.2f} s: {method_frames / ours:7.1f} "
        f"method-frames/s ({reader / ours:.2f}× the floor)"
    )
    print(
        f"read + join + score in one pass, one thread (no units, store, provenance): {one:.2f} s: "
        f"{method_frames / one:7.1f} method-frames/s ({reader / one:.2f}× the reader alone)"
    )
    for what, times in (("evaluate_bags", pipeline), ("the dispeval bag command", command)):
        for jobs, seconds in times.items():
            rate = frames[jobs] / seconds
            print(
                f"{what}, --jobs {jobs}: {frames[jobs]} matched method-frames in {seconds:.2f} s: "
                f"{rate:7.1f} method-frames/s ({rate / floor:.2f}× the reader alone, "
                f"{one / seconds:.2f}× the one pass)"
            )
    for what, runner in (
        (
            "evaluate_bags",
            lambda: pipeline_run(bag, config, root / "threads"),
        ),
        ("the dispeval bag command", lambda: bag_command(bag, root / "threads-command", 1)),
    ):
        wait_for_idle(args.idle_cores)
        wall, cpu = cpu_per_thread(runner)
        threads = ", ".join(f"{name} {seconds:.2f} s" for name, seconds in sorted(cpu.items()))
        total = sum(cpu.values())
        print(
            f"CPU per thread, {what} --jobs 1: {wall:.2f} s wall, {threads}: {total:.2f} s, "
            f"{total / wall:.2f} cores busy"
        )
    load = " ".join(f"{value:.2f}" for value in os.getloadavg())
    print(f"load average after: {load}")


if __name__ == "__main__":
    main()
