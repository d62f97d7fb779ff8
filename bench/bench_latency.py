"""What recording latency costs `dispeval bag`: the command with its timing path on and off.

    python bench/bench_latency.py [--frames 60] [--rounds 5] [--bag PATH] [--storage ...]

The bag is bench_bag.py's (a synthetic 1242×375 drive with three methods, written as make-bag
writes it, or --bag). The whole command runs in this process (--jobs 1, kernels loaded), its
rounds interleaved on, off, off, on, … so a busy moment of the shared machine hurts both
alike. *Off* is the store of a database written before arrival times were (its
``records_timing`` answers no, patched in this process only): no timing rows written, no
latency summary, no timing cells in the CSV, no timing.json. What stays on even then (the
join's arrival per estimate, the ``FrameTiming`` records, their rows) is timed apart on the
bag's own arrivals, as is each part of the path, as a share of the whole run. Prints the best
and the median of each, their ratios and the load average; asserts nothing (machines are noisy).
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from unittest import mock

from bench_bag import METHODS, bag_command, best, warm_up, write_drive  # bench/ is on sys.path

from dispeval_ros.core.records import FrameTiming
from dispeval_ros.io.store import ResultsStore, prepare_unit
from dispeval_ros.io.store.reader import ResultsReader
from dispeval_ros.offline.make_bag import bag_config
from dispeval_ros.offline.memory import keep_frames_on_the_heap
from dispeval_ros.summary import sequence_timing


@contextmanager
def timing_off() -> Iterator[None]:
    """The store as one written before latency was recorded (this process only)."""
    with mock.patch.object(ResultsReader, "records_timing", return_value=False):
        yield


def load() -> str:
    """The load average (1, 5, 15 min)."""
    return " ".join(f"{value:.2f}" for value in os.getloadavg())


def whole_runs(bag: Path, root: Path, rounds: int) -> dict[str, list[float]]:
    """Seconds of each `dispeval bag --jobs 1` run, on and off, interleaved (ABBA)."""
    times: dict[str, list[float]] = {"on": [], "off": []}
    for round_ in range(rounds):
        for kind in ("on", "off") if round_ % 2 == 0 else ("off", "on"):
            out = root / f"{kind}-{round_}"
            started = time.perf_counter()
            if kind == "off":
                with timing_off():
                    bag_command(bag, out, 1)
            else:
                bag_command(bag, out, 1)
            times[kind].append(time.perf_counter() - started)
    return times


def parts(out: Path, root: Path, rounds: int) -> dict[str, float]:
    """Each part of the timing path on the run's own arrivals: name → seconds per run."""
    with ResultsStore.open(out) as store:
        sequence = store.sequences()[0]
        found = store.timing(sequence) or {}
    entries = [entry for method in found.values() for entry in method]
    fields = [(e.sequence, e.stamp, e.method, e.estimate_stamp, e.arrival) for e in entries]

    def join() -> None:  # stream/join.py's arrival per estimate, stream/core.py's copy of it
        for _, _, method, sent, arrival in fields:
            arrivals = {method: arrival}
            kept: dict[str, int] = {}
            stamps: dict[str, int] = {}
            if method in arrivals:
                kept[method] = arrivals[method]
                stamps[method] = sent

    def records() -> list[FrameTiming]:  # offline/units.py: one record per joined estimate
        return [FrameTiming(*row) for row in fields]

    def rows() -> None:  # io/store/rows.py: the timing rows of a unit
        prepare_unit(sequence, "000000", [], timing=entries)

    def added(timing: list[FrameTiming], name: str) -> float:
        """Seconds of adding a unit (only these timing rows) to a new database, its commit."""
        with ResultsStore.create(root / name, {}) as results:
            prepared = prepare_unit(sequence, "000000", [], timing=timing)
            started = time.perf_counter()
            results.add_prepared(prepared)
            return time.perf_counter() - started

    def write() -> float:  # io/store/writer.py: the rows into the timing table, less the commit
        with_rows = [added(entries, f"timing-{i}") for i in range(3 * rounds)]
        without = [added([], f"empty-{i}") for i in range(3 * rounds)]
        return statistics.median(with_rows) - statistics.median(without)

    def summary() -> None:  # summary.py + core/timing.py: read the table, summarise
        with ResultsStore.open(out) as results:
            sequence_timing(results, sequence)

    timed: dict[str, Callable[[], Any]] = {
        "join: arrival per estimate": join,
        "FrameTiming records": records,
        "timing rows of the unit": rows,
    }
    costs = {name: best(rounds, run) for name, run in timed.items()}
    costs["timing-table writes (median)"] = max(0.0, write())
    opened = best(rounds, lambda: ResultsStore.open(out).close())
    costs["latency summary (read + summarise)"] = max(0.0, best(rounds, summary) - opened)
    costs["_estimates"] = float(len(entries))
    return costs


def main() -> None:
    """Write (or reuse) the bag, run the command on and off, then time the parts."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--storage", default="rosbag2-mcap")
    parser.add_argument("--bag", type=Path, help="reuse a bag bench_bag.py wrote before")
    parser.add_argument("--rounds", type=int, default=6, help="runs of each, interleaved")
    args = parser.parse_args()
    keep_frames_on_the_heap()  # as the pipeline does
    root = Path(tempfile.mkdtemp(prefix="dispeval-bench-latency-"))
    bag = args.bag or write_drive(root / "drive", args.frames, args.storage)
    warm_up(bag, bag_config(METHODS), root)
    print(f"load average before: {load()}")
    times = whole_runs(bag, root, args.rounds)
    on, off = times["on"], times["off"]
    paired = statistics.median(a / b for a, b in zip(on, off, strict=True))
    print(f"\n`dispeval bag --jobs 1`, {args.rounds} runs each, interleaved (ABBA):")
    for kind, runs in times.items():
        listed = " ".join(f"{seconds:.3f}" for seconds in runs)
        print(
            f"  timing {kind:3s}: best {min(runs):.3f} s, median {statistics.median(runs):.3f} s"
            f"  ({listed})"
        )
    print(
        f"  with / without: best {min(on) / min(off):.4f}, median "
        f"{statistics.median(on) / statistics.median(off):.4f}, median of the paired rounds "
        f"{paired:.4f}"
    )
    costs = parts(root / "on-0", root, max(3, args.rounds))
    estimates = int(costs.pop("_estimates"))
    whole = min(on)
    print(f"\nthe timing path in parts ({estimates} estimates; best of {max(3, args.rounds)}):")
    for name, seconds in costs.items():
        print(f"  {name:36s} {seconds * 1e3:8.3f} ms  {100 * seconds / whole:6.3f} % of the run")
    total = sum(costs.values())
    print(
        f"  {'all parts':36s} {total * 1e3:8.3f} ms  {100 * total / whole:6.3f} % of the run "
        f"({whole:.3f} s, best with timing on)"
    )
    print(f"load average after: {load()}")


if __name__ == "__main__":
    main()
