"""View-prediction error (vpe): the numba kernel against a plain numpy implementation.

Prints timings and ratios only (machines are noisy: nothing here is asserted). Run:

    python bench/bench_vpe.py [--repeat N]

Frame: KITTI 2015 000005_10 (1242×375) with OpenCV SGBM's estimate when the shared data is
present (``DISPEVAL_DATA`` or ``../shared/data``), else a synthetic 1242×375 textured pair.
Both implementations score the ``ignore`` policy (numpy has no KITTI interpolation to copy)
on the criterion ``all`` and must agree; the numba path is also timed under ``interpolate``
(which adds the KITTI interpolation of the estimate) and with the ``texture`` criteria, and
the per-frame image work apart: the GT-free criteria of a new left image (texture partition),
and of the same left image again (reused, compared by content). The process is pinned to one
core.
"""

from __future__ import annotations

import argparse
import itertools
import os
from pathlib import Path

import cv2
import numpy as np
from bench_scoring import timed  # this folder is on sys.path when run as a script

from dispeval_ros.core.gtfree import GroundTruthFree
from dispeval_ros.testbed.methods import default_methods

DATA = Path(
    os.environ.get("DISPEVAL_DATA") or Path(__file__).resolve().parents[2] / "shared" / "data"
)
SHAPE = (375, 1242)


def numpy_vpe(left: np.ndarray, right: np.ndarray, est: np.ndarray) -> float:
    """The straightforward numpy way (holes left out): z-buffer by ``maximum.at``, gathers."""
    height, width = est.shape
    valid = np.isfinite(est) & (est > 0)
    d = np.where(valid, est, 0).astype(np.float64)
    source = np.arange(width)[None, :] - d
    target = np.floor(source + 0.5).astype(np.int64)
    rows = np.broadcast_to(np.arange(height)[:, None], est.shape)
    lands = valid & (target >= 0) & (target < width)
    zbuffer = np.full(height * width, -np.inf)
    np.maximum.at(zbuffer, (rows * width + target)[lands], d[lands])
    inside = valid & (source >= 0) & (source <= width - 1)
    flat = (rows * width + np.clip(target, 0, width - 1)).ravel()
    visible = inside & ~(zbuffer[flat].reshape(est.shape) > d + 1.0)
    x0 = np.clip(np.floor(source), 0, width - 1).astype(np.int64)
    x1 = np.minimum(x0 + 1, width - 1)
    a = source - x0
    predicted = (1 - a) * right[rows, x0] + a * right[rows, x1]
    error = np.abs(left.astype(np.float64) - predicted)
    return float(error[visible].sum() / visible.sum())


def frame() -> tuple[str, np.ndarray, np.ndarray, np.ndarray]:
    """(name, left, right, estimate) of the benchmark frame."""
    folder = DATA / "kitti-2015" / "000005_10"
    if (folder / "stereo_left.png").is_file():
        left = cv2.imread(str(folder / "stereo_left.png"), cv2.IMREAD_GRAYSCALE)
        right = cv2.imread(str(folder / "stereo_right.png"), cv2.IMREAD_GRAYSCALE)
        name = "KITTI 000005_10"
    else:
        rng = np.random.default_rng(0)
        left = cv2.GaussianBlur(rng.integers(0, 256, SHAPE).astype(np.uint8), (5, 5), 1.0)
        right = np.roll(left, -20, axis=1)
        name = "synthetic"
    method = next(m for m in default_methods(left.shape[1]) if m.name == "sgbm")
    return name, left, right, method.compute(left, right)


def main() -> None:
    """Time both implementations on the frame and print the ratios."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=30, help="timed runs per case")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    name, left, right, est = frame()
    ignore = GroundTruthFree(("all",), "ignore")
    pair = ignore.pair(left, right)
    fast = ignore.score(pair, est)["gtfree:all"]["vpe"]
    plain = numpy_vpe(left, right, est)
    if not np.isclose(fast, plain, rtol=1e-9):
        raise SystemExit(f"numba vpe {fast!r} != numpy vpe {plain!r}")
    numba_ms = timed(lambda: ignore.score(pair, est), args.repeat)
    numpy_ms = timed(lambda: numpy_vpe(left, right, est), max(3, args.repeat // 5))
    print(f"vpe of SGBM on {name} ({left.shape[1]}×{left.shape[0]}), one core; vpe = {fast:.4f}")
    print(f"{'case':<40} {'ms/frame':>9} {'vs numpy':>9}")
    print(f"{'numpy (ignore, all)':<40} {numpy_ms:9.2f} {1.0:8.1f}×")
    print(f"{'numba (ignore, all)':<40} {numba_ms:9.2f} {numpy_ms / numba_ms:8.1f}×")
    for missing, criteria in (("interpolate", ("all",)), ("interpolate", ("all", "texture"))):
        free = GroundTruthFree(criteria, missing)
        scored = free.pair(left, right)
        ms = timed(lambda: free.score(scored, est), args.repeat)  # noqa: B023 - timed at once
        case = f"numba ({missing}, {' + '.join(criteria)})"
        print(f"{case:<40} {ms:9.2f} {numpy_ms / ms:8.1f}×")
    textured = GroundTruthFree(("all", "texture"), "interpolate")
    alternating = itertools.cycle((left, np.ascontiguousarray(left[:, ::-1])))
    new_ms = timed(lambda: textured.pair(next(alternating), right), args.repeat)
    same_ms = timed(lambda: textured.pair(left, right), args.repeat)
    print(f"{'GT-free criteria, new left image':<40} {new_ms:9.2f}")
    print(f"{'GT-free criteria, same left image':<40} {same_ms:9.2f}")


if __name__ == "__main__":
    main()
