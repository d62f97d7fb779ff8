"""Three methods at 1242×375 and 30 Hz over DDS on this machine, every part in its own process.

    python bench/bench_dds.py [--seconds 10] [--rate 30] [--distinct 30]

1. Raw-CDR micro-benchmark (this process, two participants): serialise + write one 1242×375
   ``DisparityImage``, take + decode it; cyclonedds-python's own Python deserialiser beside.
2. ``dispeval live`` runs as a separate process (shipped localhost configuration, a domain
   derived from the pid, default queue of 4).
3. A publisher process (this file with ``--publish``) renders ``--distinct`` driving frames with
   the test bed (GT + bm_fast, sgbm, sgbm_3way), then publishes them in a loop at ``--rate``
   as a stereo pipeline does: CameraInfo pair and GT image at the tick, each method's
   DisparityImage 2/5/8 ms later, every header stamped with the wall clock of the tick.
4. This process subscribes to ``/dispeval/scores`` and measures the sustained rate and the
   latency from publication (the tick's wall-clock stamp, which the scores carry as their
   header stamp) to the scores' arrival; drops come from the live process's database.

Prints numbers; asserts nothing. Target: 30 Hz sustained, p99 ≤ 50 ms.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from dispeval_ros.dds import environment
from dispeval_ros.offline.make_bag import GT_TOPIC, LEFT_INFO, RIGHT_INFO, disparity_topic

METHODS = ("bm_fast", "sgbm", "sgbm_3way")
WIDTH, HEIGHT = 1242, 375
DISPARITY = "stereo_msgs/msg/DisparityImage"


def _restamped(msg: Any, stamp: int) -> Any:
    """The message with its (and its image's) header stamp set to ``stamp`` ns."""
    header = msg.header
    new = dataclasses.replace(
        header,
        stamp=dataclasses.replace(header.stamp, sec=stamp // 10**9, nanosec=stamp % 10**9),
    )
    changes: dict[str, Any] = {"header": new}
    if hasattr(msg, "image"):
        changes["image"] = dataclasses.replace(msg.image, header=new)
    return dataclasses.replace(msg, **changes)


def publish(domain: int, seconds: float, rate: float, distinct: int) -> None:
    """The publisher process: render, wait for the evaluator, publish at the rate."""
    from dispeval_ros.dds.transport import DdsTransport
    from dispeval_ros.dds.wire import PLAYBACK
    from dispeval_ros.io.encoders import camera_info_to_msg, disparity_to_msg, image_to_msg
    from dispeval_ros.testbed import default_methods, make_driving_sequence

    transport = DdsTransport(domain)
    store = transport.typestore
    methods = [m for m in default_methods(WIDTH) if m.name in METHODS]
    frames = []
    for frame in make_driving_sequence(distinct, WIDTH, HEIGHT, fps=rate, seed=11):
        camera = frame.camera
        messages: list[tuple[str, Any, float]] = [
            (LEFT_INFO, camera_info_to_msg(store, camera, WIDTH, HEIGHT, 0, "l", False), 0.0),
            (RIGHT_INFO, camera_info_to_msg(store, camera, WIDTH, HEIGHT, 0, "r", True), 0.0),
            (GT_TOPIC, image_to_msg(store, frame.gt_left, 0, "l", "32FC1"), 0.0),
        ]
        for index, method in enumerate(methods):
            disparity = method.compute(frame.left, frame.right)
            msg = disparity_to_msg(
                store,
                disparity,
                0,
                "l",
                camera.f,
                camera.baseline,
                method.min_disparity,
                method.max_disparity,
            )
            messages.append((disparity_topic(method.name), msg, (2 + 3 * index) / 1000))
        frames.append(messages)
    types = {
        LEFT_INFO: "sensor_msgs/msg/CameraInfo",
        RIGHT_INFO: "sensor_msgs/msg/CameraInfo",
        GT_TOPIC: "sensor_msgs/msg/Image",
    }
    types.update({disparity_topic(m): DISPARITY for m in METHODS})
    writers = {
        topic: transport.writer(topic, msgtype, PLAYBACK) for topic, msgtype in types.items()
    }
    deadline = time.monotonic() + 60
    while any(w.matched() == 0 for w in writers.values()) and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.3)
    print("publishing", flush=True)
    period = 1.0 / rate
    total = round(seconds * rate)
    costs: list[float] = []
    last: list[float] = []
    started = time.perf_counter()
    for i in range(total):
        tick = started + i * period
        wait = tick - time.perf_counter()
        if wait > 0:
            time.sleep(wait)
        stamp = time.time_ns()
        for topic, msg, delay in frames[i % len(frames)]:
            wait = tick + delay - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
            begun = time.perf_counter()
            writers[topic].publish(_restamped(msg, stamp))
            costs.append(time.perf_counter() - begun)
        last.append((time.time_ns() - stamp) / 1e6)
    elapsed = time.perf_counter() - started
    print(
        f"published {total} frames ({6 * total} messages) in {elapsed:.2f} s = "
        f"{total / elapsed:.1f} Hz; median restamp+serialise+write per message "
        f"{statistics.median(costs) * 1e3:.2f} ms",
        flush=True,
    )
    print(
        f"a frame's last message left {np.percentile(last, 50):.1f} ms (p50), "
        f"{np.percentile(last, 99):.1f} ms (p99), {max(last):.1f} ms (max) after its stamp "
        "(8 ms by design)",
        flush=True,
    )
    time.sleep(0.5)
    transport.close()


def micro(domain: int, repeats: int = 40) -> None:
    """Publish and take one 1242×375 DisparityImage through the raw-CDR path, timed."""
    from dispeval_ros.dds.idl import struct_for
    from dispeval_ros.dds.transport import DdsTransport
    from dispeval_ros.dds.wire import PLAYBACK, SENSOR_DATA
    from dispeval_ros.io.encoders import disparity_to_msg

    first, second = DdsTransport(domain), DdsTransport(domain)
    try:
        store = first.typestore
        rng = np.random.default_rng(1)
        msg = disparity_to_msg(
            store, rng.random((HEIGHT, WIDTH), dtype=np.float32) * 90, 1, "l", 721.5, 0.54, 0, 96
        )
        writer = first.writer("/bench/disparity", DISPARITY, PLAYBACK)
        reader = second.reader("/bench/disparity", DISPARITY, SENSOR_DATA)
        deadline = time.monotonic() + 10
        while (writer.matched() == 0 or reader.matched() == 0) and time.monotonic() < deadline:
            time.sleep(0.02)
        serialise, write, take, decode = [], [], [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            payload = writer.serialize(msg)
            t1 = time.perf_counter()
            writer.write_cdr(payload)
            t2 = time.perf_counter()
            samples: list[tuple[bytes, Any]] = []
            while not samples:
                samples = reader.take(1)
            t3 = time.perf_counter()
            reader.decode(samples[0][0])
            t4 = time.perf_counter()
            serialise.append(t1 - t0)
            write.append(t2 - t1)
            take.append(t3 - t2)
            decode.append(t4 - t3)
        struct = struct_for(store, DISPARITY)
        t0 = time.perf_counter()
        struct.deserialize(samples[0][0])  # type: ignore[attr-defined]
        python_cdr = time.perf_counter() - t0
    finally:
        first.close()
        second.close()

    def ms(values: list[float]) -> str:
        return f"{statistics.median(values) * 1e3:.2f} ms"

    size = len(samples[0][0]) / 1e6
    print(
        f"raw CDR, one {WIDTH}×{HEIGHT} DisparityImage ({size:.2f} MB), median of {repeats}:\n"
        f"  publish: rosbags serialise {ms(serialise)} + DDS write {ms(write)}\n"
        f"  take: DDS take (until it is there) {ms(take)} + rosbags decode {ms(decode)}\n"
        f"  (cyclonedds-python's own Python deserialiser on the same bytes: "
        f"{python_cdr * 1e3:.0f} ms)"
    )


def main() -> None:
    """Run the processes, measure, report."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--rate", type=float, default=30.0)
    parser.add_argument("--distinct", type=int, default=30)
    parser.add_argument(
        "--live-args", default="", help="extra options for dispeval live (e.g. '--queue-size 8')"
    )
    parser.add_argument("--publish", type=int, metavar="DOMAIN", help=argparse.SUPPRESS)
    args = parser.parse_args()
    config = environment.localhost_config()
    os.environ["CYCLONEDDS_URI"] = config.as_uri()
    if args.publish is not None:
        publish(args.publish, args.seconds, args.rate, args.distinct)
        return
    domain = 1 + os.getpid() % 200
    micro(domain)

    from dispeval_ros.dds.transport import DdsTransport
    from dispeval_ros.dds.wire import DIAGNOSTIC_ARRAY, SCORES_TOPIC, SUMMARIZER_INPUT
    from dispeval_ros.io.store import ResultsStore

    arrivals: list[tuple[int, int]] = []
    lock = threading.Lock()

    def arrived(received: Any) -> None:
        now = time.time_ns()
        stamp = received.msg.header.stamp
        with lock:
            arrivals.append((now, stamp.sec * 10**9 + stamp.nanosec))

    scratch = tempfile.TemporaryDirectory(prefix="bench-dds-")
    out = Path(scratch.name) / "live"
    env = {k: v for k, v in os.environ.items() if k != "ROS_DOMAIN_ID"}
    dds = ["--domain-id", str(domain), "--dds-config", str(config)]
    live_cmd = [sys.executable, "-m", "dispeval_ros", "live", "--gt", GT_TOPIC]
    for method in METHODS:
        live_cmd += ["--method", f"{method}={disparity_topic(method)}"]
    live_cmd += ["--camera-info", LEFT_INFO, RIGHT_INFO, "--out", str(out), "--quiet", *dds]
    live_cmd += args.live_args.split()
    transport = DdsTransport(domain)
    reader = transport.reader(SCORES_TOPIC, DIAGNOSTIC_ARRAY, SUMMARIZER_INPUT)
    thread = transport.reader_thread("bench")
    thread.add(reader, arrived)
    thread.start()
    live = subprocess.Popen(
        live_cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    publisher = subprocess.Popen(
        [
            sys.executable,
            __file__,
            "--publish",
            str(domain),
            "--seconds",
            str(args.seconds),
            "--rate",
            str(args.rate),
            "--distinct",
            str(args.distinct),
        ],
        env=env,
        stdout=subprocess.PIPE,
        text=True,
    )
    print(
        f"\nrendering {args.distinct} frames of {WIDTH}×{HEIGHT} and running "
        f"{len(METHODS)} OpenCV methods on them in the publisher process…",
        flush=True,
    )
    assert publisher.stdout is not None
    for line in publisher.stdout:
        print("publisher:", line.rstrip(), flush=True)
    publisher.wait()
    time.sleep(2.0)
    live.send_signal(signal.SIGINT)
    live_output, _ = live.communicate(timeout=120)
    transport.close()
    this_run = next((line for line in live_output.splitlines() if line.startswith("this run")), "")
    print("live:", this_run or live_output[-2000:])

    with lock:
        data = sorted(arrivals, key=lambda item: item[1])
    if len(data) < 2:
        print("no scores received")
        return
    latencies = np.array([(now - stamp) / 1e6 for now, stamp in data])
    span = (data[-1][1] - data[0][1]) / 1e9
    with ResultsStore.open(out) as store:
        counts = {}
        for sequence in store.sequences():
            for method, count in store.match_counts(sequence).items():
                counts[method] = count
    scratch.cleanup()
    expected = round(args.seconds * args.rate)
    print(
        f"\nscores received for {len(data)} of {expected} published frames; sustained "
        f"{(len(data) - 1) / span:.1f} Hz over {span:.1f} s"
    )
    print(
        "drops per method (live's database: matched / unmatched / dropped / failed): "
        + ", ".join(
            f"{m} {c.matched}/{c.unmatched}/{c.dropped}/{c.failed}" for m, c in counts.items()
        )
    )
    print(
        f"latency, publication (GT tick) → scores received here: "
        f"p50 {np.percentile(latencies, 50):.1f} ms, p99 {np.percentile(latencies, 99):.1f} ms, "
        f"max {latencies.max():.1f} ms (target: 30 Hz, p99 ≤ 50 ms)"
    )


if __name__ == "__main__":
    main()
