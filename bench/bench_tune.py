"""``dispeval tune``: the evaluation's share of a sweep, against the OpenCV compute it judges.

Prints timings and ratios only (machines are noisy: nothing here is asserted). Run:

    python bench/bench_tune.py [--repeat N]

Scene: KITTI 2015 000005_10 (1242×375, sparse GT, camera) from the shared data
(``DISPEVAL_DATA`` or ``../shared/data``). Space: ``config/tune_sgbm.yaml`` with
``disparity_range`` 128 (KITTI's disparities). Timed ``--repeat`` times, interleaved, and the
medians kept: every configuration's OpenCV map (the baseline), scoring those maps, and a whole
sweep into a results database (``run_sweep``, one process), whose time beyond the maps is what
the evaluation, the rows and the database cost. The process is pinned to one core.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import cv2

from dispeval_ros.core import Evaluator
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.tuning.space import read_space, space_from_document
from dispeval_ros.offline.tuning.sweep import load_scene, run_sweep

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("DISPEVAL_DATA") or ROOT.parent / "shared" / "data")


def timed_ms(work: Callable[[], object]) -> float:
    """Wall time of ``work()`` in ms."""
    start = time.perf_counter()
    work()
    return (time.perf_counter() - start) * 1e3


def main() -> None:
    """Time the maps, their scoring and a whole sweep; print the shares."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="timed runs of each part")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    cv2.setNumThreads(1)  # one core: OpenCV's pool was sized before the pinning
    scene = DATA / "kitti-2015" / "000005_10"
    if not scene.is_dir():
        raise SystemExit(f"{scene}: not found (set DISPEVAL_DATA to the shared data)")
    example = read_space(ROOT / "config" / "tune_sgbm.yaml").record()
    example["axes"]["disparity_range"] = [128]
    space = space_from_document(
        {"family": example["family"], "parameters": example["axes"]}, "bench"
    )
    configurations = space.configurations()
    evaluator = Evaluator()
    (frame,) = load_scene(scene, evaluator)
    for configuration in configurations:  # warm up: matchers created, kernels compiled
        evaluator.score(frame.reference, configuration.method.compute(frame.left, frame.right))
    estimates = [c.method.compute(frame.left, frame.right) for c in configurations]
    maps, scores, sweeps = [], [], []
    for _ in range(args.repeat):  # interleaved, so that a change of load hits all three
        maps.append(
            timed_ms(lambda: [c.method.compute(frame.left, frame.right) for c in configurations])
        )
        scores.append(timed_ms(lambda: [evaluator.score(frame.reference, e) for e in estimates]))
        with tempfile.TemporaryDirectory() as folder:
            store = ResultsStore.create(Path(folder), {"bench": "tune"})
            with store:
                sweeps.append(
                    timed_ms(
                        lambda s=store: run_sweep(
                            s, [scene], {0: [frame]}, configurations, evaluator
                        )
                    )
                )
    compute, score, sweep = (statistics.median(t) for t in (maps, scores, sweeps))
    count = len(configurations)
    width, height = frame.left.shape[1], frame.left.shape[0]
    print(f"{count} SGBM configurations on KITTI 000005_10 ({width}×{height}), one core")
    print(f"{'part':<44} {'ms/config':>10} {'vs OpenCV':>10}")
    print(f"{'OpenCV map (baseline)':<44} {compute / count:10.2f} {1.0:9.3f}×")
    print(
        f"{'scoring the map (Evaluator.score)':<44} {score / count:10.2f} {score / compute:9.3f}×"
    )
    print(
        f"{'whole sweep (maps, scores, rows, database)':<44} {sweep / count:10.2f} "
        f"{sweep / compute:9.3f}×"
    )
    print(
        f"beyond the maps, the sweep spends {100 * (sweep - compute) / compute:.1f} % of their time"
    )


if __name__ == "__main__":
    main()
