"""Partition build per GT map against a plain numpy build of the same partition, in one run.

Prints timings and ratios only (nothing is asserted about time) and checks that both builds
give the same cells. Both builds are timed in alternating rounds, and the ratio is the median of
the rounds' ratios (a slow phase of a shared machine then hits both). Run:

    python bench/bench_partition.py [--repeat N]

The partition is the default one (all + visibility + depth: z-buffer occlusion, boundaries
from GT jumps, 3-means depth classes), built by ``Evaluator.reference`` (which also gathers the
GT in partition order for scoring). The numpy build does the same steps with whole-array
operations: a boolean mask per step, ``np.maximum.at`` for the z-buffer, Lloyd's 3-means on
every valid value, a stable argsort for the order. The process is pinned to one core.
"""

from __future__ import annotations

import statistics
import sys
from pathlib import Path

import numpy as np
from bench_scoring import CRITERIA, run_on_frames, timed

from dispeval_ros import Camera, Evaluator

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))  # bag_support, ...
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test" / "core"))
from test_partition_reference import numpy_partition

ROUNDS = 7
"""Rounds of both builds, alternating; the ratio printed is the median of the rounds' ratios."""


def bench_case(gt: np.ndarray, camera: Camera, label: str, repeat: int) -> None:
    """Time both builds and check they agree."""
    evaluator = Evaluator(CRITERIA)
    ours = evaluator.reference(gt, camera)
    cells, order, offsets, gt_sorted = numpy_partition(gt)
    same = (
        np.array_equal(ours.partition.cells, cells)
        and np.array_equal(ours.partition.order, order)
        and np.array_equal(ours.partition.offsets, offsets)
        and np.array_equal(ours.gt_sorted, gt_sorted)
    )
    ours_ms: list[float] = []
    numpy_ms: list[float] = []
    for _ in range(ROUNDS):  # interleaved: a slow phase of a shared machine hits both builds
        ours_ms.append(timed(lambda: evaluator.reference(gt, camera), max(3, repeat // ROUNDS)))
        numpy_ms.append(timed(lambda: numpy_partition(gt), 3))
    ratios = sorted(n / o for n, o in zip(numpy_ms, ours_ms, strict=True))
    t_ours, t_numpy = statistics.median(ours_ms), statistics.median(numpy_ms)
    height, width = gt.shape
    print(f"\n{width}×{height}  {label}: {int((cells >= 0).sum())} valid GT points")
    print(f"  numpy build                {t_numpy:8.2f} ms   1.0×")
    print(
        f"  Evaluator.reference        {t_ours:8.2f} ms   {statistics.median(ratios):5.1f}× faster"
        f" (median of {ROUNDS} interleaved rounds; {ratios[0]:.1f}–{ratios[-1]:.1f}×)"
    )
    print(f"  same cells, order, offsets and sorted GT: {same}")


def main() -> None:
    """Run every case."""
    run_on_frames(
        __doc__ or "",
        "partition builds",
        20,
        lambda frame, n: bench_case(frame[0], frame[2], frame[3], n),
    )


if __name__ == "__main__":
    main()
