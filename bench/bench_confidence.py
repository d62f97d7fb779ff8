"""Confidence measures per 1242×375 frame with an 8-bit confidence, against a numpy sort.

Prints timings and ratios only (machines are noisy: nothing here is asserted). Run:

    python bench/bench_confidence.py [--repeat N]

Frames: a dense one (GT at every pixel: the worst case, 465 750 points) and, where the shared
data is (``DISPEVAL_DATA`` or ``../shared/data``), KITTI 2015 000005_10 (its LiDAR GT, 91 126
points). Estimate: the GT plus Student-t noise with 8 % holes; confidence: 8-bit, informative.
Criteria ``all``, ``visibility``, ``depth``; thresholds 0.5, 2, 4 with D1, MAE and the depth
error. Rows: ``ConfidenceScorer.score`` (every curve's sums, all criteria) under ``ignore``
(no estimate interpolation) and ``interpolate`` (the KITTI interpolation included, which a
frame's ordinary scoring pays too); reading every curve off the sums; and the baseline, plain
numpy doing the same from the definitions: per criterion a stable sort of the confidence and
cumulative sums of each measure (its areas are checked equal first). The process is pinned to
one core; the best and the median CPU times of the rounds are printed.
"""

from __future__ import annotations

import argparse
import functools
import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from dispeval_ros.core import Evaluator
from dispeval_ros.core.camera import Camera
from dispeval_ros.core.confidence import (
    ConfidenceScorer,
    ConfidenceSums,
    Curve,
    grading,
    parse_preset,
)
from dispeval_ros.io import load_scene

DATA = Path(os.environ.get("DISPEVAL_DATA", Path(__file__).resolve().parents[2] / "shared/data"))
CRITERIA = ("all", "visibility", "depth")
THRESHOLDS = (0.5, 2.0, 4.0)
SHAPE = (375, 1242)


def frames() -> list[tuple[str, np.ndarray, Camera | None, dict[str, np.ndarray]]]:
    """(name, GT, camera, official masks) of the frames timed."""
    rows, cols = np.mgrid[0 : SHAPE[0], 0 : SHAPE[1]]
    dense = (8 + 40 * (rows / SHAPE[0]) ** 2 + 4 * np.sin(cols / 31.0)).astype(np.float32)
    found = [("dense 1242×375", dense, Camera(f=721.5, baseline=0.54), {})]
    kitti = DATA / "kitti-2015" / "000005_10"
    if kitti.is_dir():
        scene = load_scene(kitti)
        found.append(("KITTI 000005_10", scene.gt, scene.camera, scene.masks))
    else:
        print(f"(no shared data at {DATA}: the dense frame only)")
    return found


def inputs(gt: np.ndarray, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    noise = rng.standard_t(3, gt.shape) * 1.2
    est = np.where(gt > 0, gt + noise, 0).astype(np.float32)
    est[rng.random(gt.shape) < 0.08] = 0.0
    confidence = np.clip(220 - 40 * np.abs(noise) + rng.normal(0, 30, gt.shape), 0, 255)
    return est, confidence.astype(np.uint8)


def numpy_areas(
    masks: list[np.ndarray], gt: np.ndarray, est: np.ndarray, rank: np.ndarray
) -> list[float]:
    """Every curve's area per criterion by a stable sort (ties as the definition averages)."""
    areas = []
    for mask in masks:
        d = gt[mask].astype(np.float64)
        raw = est[mask].astype(np.float64)
        valid = raw > 0
        d, error, order_of = d[valid], np.abs(raw[valid] - d[valid]), rank[mask][valid]
        if not error.size:
            continue
        order = np.argsort(order_of, kind="stable")
        ranked = order_of[order]
        first = np.flatnonzero(np.r_[True, ranked[1:] != ranked[:-1]])
        size = np.diff(np.r_[first, ranked.size])
        n = error.size
        k = np.arange(1, n + 1, dtype=np.float64)
        log_term = np.zeros(n)
        log_term[1:] = np.log(k[1:] / (k[1:] - 1))
        measures = [error > t for t in THRESHOLDS]
        measures += [(error > 3) & (error > 0.05 * d), error]
        for values in measures:
            e = np.repeat(np.add.reduceat(values[order].astype(np.float64), first) / size, size)
            before = np.cumsum(e) - e
            areas.append(float(np.sum((before - (k - 1) * e) / n * log_term + e / n)))
    return areas


def read_curves(sums: ConfidenceSums, criteria: list[str]) -> list[Curve]:
    return [sums.curve(c, m) for c in criteria for m in sums.measures()]


def timed(call: Callable[[], object], repeat: int) -> tuple[float, float]:
    call()
    times = []
    for _ in range(repeat):
        start = time.process_time()
        call()
        times.append(time.process_time() - start)
    return min(times) * 1e3, float(np.median(times)) * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=20, help="rounds per case (default 20)")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    print(f"load average at start: {os.getloadavg()[0]:.2f}; one core, {args.repeat} rounds")
    preset = parse_preset("wls")
    level = grading(preset, np.dtype(np.uint8))
    for name, gt, camera, masks in frames():
        est, confidence = inputs(gt)
        print(f"\n{name}")
        rows = []
        for missing in ("ignore", "interpolate"):
            evaluator = Evaluator(criteria=CRITERIA, missing=missing)
            reference = evaluator.reference(gt, camera, masks=masks)
            scorer = ConfidenceScorer(evaluator, preset, THRESHOLDS)
            sums = scorer.score(reference, est, confidence)
            rows.append(
                (
                    f"score ({missing})",
                    timed(functools.partial(scorer.score, reference, est, confidence), args.repeat),
                )
            )
            if missing == "ignore":
                points = int(reference.partition.order.shape[0])
                criteria = [c for c, n in zip(sums.criteria, sums.points, strict=True) if n > 0]
                masks_of = [reference.partition.mask(c) for c in criteria]
                rank = level.level(confidence)
                ours = [
                    sums.curve(c, m).auc / (100 if m != "mae" else 1)
                    for c in criteria
                    for m in (*(f"bad_{t:g}" for t in THRESHOLDS), "d1", "mae")
                ]
                theirs = numpy_areas(masks_of, reference.gt, est, rank)
                assert np.allclose(ours, theirs, rtol=1e-9, equal_nan=True), "areas differ"
                rows.append(
                    (
                        "curves from the sums",
                        timed(functools.partial(read_curves, sums, criteria), args.repeat),
                    )
                )
                baseline = timed(
                    functools.partial(numpy_areas, masks_of, reference.gt, est, rank),
                    max(3, args.repeat // 4),
                )
        print(f"  {points} points, {len(criteria)} criteria with points")
        for label, (best, median) in rows:
            print(f"  {label:<24} best {best:7.2f} ms  median {median:7.2f} ms  "
                  f"numpy sort / this: {baseline[0] / best:6.1f}×")  # fmt: skip
        print(
            f"  {'numpy sort (baseline)':<24} best {baseline[0]:7.2f} ms  median {baseline[1]:7.2f} ms"
        )


if __name__ == "__main__":
    main()
