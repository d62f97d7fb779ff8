"""Per-frame scoring speed against a plain numpy baseline measured in the same run.

Prints timings and ratios only (machines are noisy: nothing here is asserted). Run:

    python bench/bench_scoring.py [--repeat N]

Scenes: synthetic driving frames with dense exact GT at 1242×375 and 1920×1080 (estimate:
OpenCV StereoSGBM, so holes are real), plus the real sparse KITTI frame when the shared data
is present. Criteria all + visibility + depth (7 criteria); measures bmp, mae, mse, mre,
sze, bmpre, d1, density. The process is pinned to one core.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from dispeval_ros import Camera, Evaluator
from dispeval_ros.testbed import default_methods, make_driving_sequence

CRITERIA = ("all", "visibility", "depth")
MEASURES = ("bmp", "mae", "mse", "mre", "sze", "bmpre", "d1", "density")
DATA = Path(
    os.environ.get("DISPEVAL_DATA")
    or Path(__file__).resolve().parents[1].parent / "shared" / "data"
)


def timed(function: Callable[[], object], repeat: int) -> float:
    """Median wall time of ``function`` in milliseconds (after one warm-up call)."""
    function()
    samples = []
    for _ in range(repeat):
        start = time.perf_counter()
        function()
        samples.append((time.perf_counter() - start) * 1e3)
    return statistics.median(samples)


def numpy_baseline(
    gt: np.ndarray,
    est: np.ndarray,
    masks: dict[str, np.ndarray],
    camera: Camera,
    delta: float,
    mu: float,
) -> dict[str, dict[str, float]]:
    """The straightforward way: a boolean mask per criterion, a numpy expression per measure.

    Missing estimates count as E = 0 (the ``thesis`` policy, which needs no interpolation).
    """
    valid_est = np.isfinite(est) & (est > 0)
    filled = np.where(valid_est, est, 0.0)
    results = {}
    for name, mask in masks.items():
        d = gt[mask].astype(np.float64)
        e_est = filled[mask].astype(np.float64)
        e = np.abs(e_est - d)
        fb = camera.fb
        results[name] = {
            "n": float(mask.sum()),
            "bmp": 100.0 * np.mean(e > delta),
            "mae": float(np.mean(e)),
            "mse": float(np.mean(e**2)),
            "mre": float(np.mean(e / d)),
            "sze": float(
                np.sum(np.abs(fb / (d + camera.doffs + mu) - fb / (e_est + camera.doffs + mu)))
            ),
            "bmpre": float(np.sum((e / d)[e > delta])),
            "d1": 100.0 * np.mean((e > 3) & (e > 0.05 * d)),
            "density": float(np.mean(valid_est[mask])),
        }
    return results


def synthetic_frame(width: int, height: int) -> tuple[np.ndarray, np.ndarray, Camera, str]:
    """One driving frame and an SGBM estimate of it."""
    frame = next(make_driving_sequence(n_frames=1, width=width, height=height, seed=3))
    sgbm = next(m for m in default_methods(width) if m.name == "sgbm")
    return frame.gt_left, sgbm.compute(frame.left, frame.right), frame.camera, "synthetic, dense GT"


def kitti_frame() -> tuple[np.ndarray, np.ndarray, Camera, str] | None:
    """The real KITTI 2015 frame (sparse LiDAR GT) with an SGBM estimate, if the data is here."""
    folder = DATA / "kitti-2015" / "000005_10"
    if not folder.is_dir():
        return None
    import cv2

    from dispeval_ros.io import load_scene

    scene = load_scene(folder)
    left = cv2.imread(str(folder / "stereo_left.png"), cv2.IMREAD_GRAYSCALE)
    right = cv2.imread(str(folder / "stereo_right.png"), cv2.IMREAD_GRAYSCALE)
    sgbm = next(m for m in default_methods(left.shape[1]) if m.name == "sgbm")
    assert scene.camera is not None
    return scene.gt, sgbm.compute(left, right), scene.camera, "KITTI 000005_10, sparse GT"


def bench_case(gt: np.ndarray, est: np.ndarray, camera: Camera, label: str, repeat: int) -> None:
    """Time partition building, fused scoring (two policies) and the numpy baseline."""
    fused = Evaluator(CRITERIA, MEASURES, missing="thesis")
    interpolating = Evaluator(CRITERIA, MEASURES, missing="interpolate")
    reference = fused.reference(gt, camera)
    partition = reference.partition
    masks = {name: partition.mask(name) for name in partition.criteria}

    t_partition = timed(lambda: fused.reference(gt, camera), max(3, repeat // 4))
    t_fused = timed(lambda: fused.score(reference, est), repeat)
    t_interp = timed(lambda: interpolating.score(reference, est), repeat)
    t_numpy = timed(lambda: numpy_baseline(gt, est, masks, camera, 1.0, 0.01), max(3, repeat // 4))
    t_array = timed(lambda: fused.score(gt, est, camera), repeat)  # GT found in the cache
    t_array_interp = timed(lambda: interpolating.score(gt, est, camera), repeat)
    others = [np.where(gt > 0, gt + shift, gt) for shift in (0.5, 1.0, 1.5)]
    for other in others:  # three more GT maps cached; scoring cycles through all four
        fused.score(other, est, camera)
    maps = [gt, *others]
    references = [fused.reference(m, camera) for m in maps]
    rounds = repeat // 4 + 1
    t_cycle = timed(lambda: [fused.score(m, est, camera) for m in maps], rounds) / 4
    t_cycle_prepared = timed(lambda: [fused.score(r, est) for r in references], rounds) / 4

    ours = fused.score(reference, est)
    theirs = numpy_baseline(gt, est, masks, camera, 1.0, 0.01)
    worst = max(
        abs(ours[c][m] - theirs[c][m]) / max(abs(theirs[c][m]), 1e-12)
        for c in partition.criteria
        for m in MEASURES
        if partition.counts()[c] > 0
    )
    height, width = gt.shape
    valid = int((partition.cells >= 0).sum())
    print(
        f"\n{width}×{height}  {label}: {valid} valid GT points, {len(partition.criteria)} criteria"
    )
    print(f"  partition build (per GT map)            {t_partition:8.2f} ms")
    print(f"  numpy baseline, thesis policy           {t_numpy:8.2f} ms   1.0×")
    print(
        f"  fused scoring, thesis policy            {t_fused:8.2f} ms   {t_numpy / t_fused:5.1f}× faster"
    )
    print(
        f"  fused scoring, interpolate (default)    {t_interp:8.2f} ms   {t_numpy / t_interp:5.1f}× faster"
    )
    print(
        f"  array API score(gt, est), GT cached     {t_array:8.2f} ms   {t_numpy / t_array:5.1f}× faster"
        f"   ({t_array / t_fused:4.2f}× the prepared reference)"
    )
    print(
        f"  array API, interpolate (default)        {t_array_interp:8.2f} ms   "
        f"{t_numpy / t_array_interp:5.1f}× faster"
        f"   ({t_array_interp / t_interp:4.2f}× the prepared reference)"
    )
    print(
        f"  array API, cycling 4 cached GT maps     {t_cycle:8.2f} ms   {t_numpy / t_cycle:5.1f}× faster"
        f"   ({t_cycle / t_cycle_prepared:4.2f}× cycling 4 prepared references)"
    )
    print(f"  largest relative difference fused vs baseline: {worst:.2e}")


def pin_to_one_core() -> None:
    """Run on one core (where the OS allows it): timings then do not depend on scheduling."""
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})


Frame = tuple[np.ndarray, np.ndarray, Camera, str]


def run_on_frames(
    description: str, what: str, repeat: int, case: Callable[[Frame, int], None]
) -> None:
    """Parse ``--repeat``, pin to one core and run ``case`` on every benchmark frame.

    Frames: synthetic 1242×375 and 1920×1080, and the KITTI frame if the data is present.
    """
    parser = argparse.ArgumentParser(description=description.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=repeat, help=f"timed {what} per measurement")
    args = parser.parse_args()
    pin_to_one_core()
    print(f"dispeval_ros {what} benchmark (one core; median of {args.repeat})")
    frames = [synthetic_frame(1242, 375), synthetic_frame(1920, 1080)]
    kitti = kitti_frame()
    if kitti is not None:
        frames.append(kitti)
    for frame in frames:
        case(frame, args.repeat)


def main() -> None:
    """Run every case."""
    run_on_frames(__doc__ or "", "scoring calls", 40, lambda frame, n: bench_case(*frame, n))


if __name__ == "__main__":
    main()
