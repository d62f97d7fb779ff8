"""Temporal measures: the ego-motion residual and flicker against plain numpy, per 1242×375 frame.

Prints timings and ratios only (machines are noisy: nothing here is asserted). Run:

    python bench/bench_egomotion.py [--repeat N]

Two frames of the test-bed drive at KITTI size (1242×375, exact motion 0.1 s apart), the
exact disparity plus Gaussian noise (σ = 0.2 px) as the estimate. Both implementations compute
the same statuses and sums (checked first); numpy is ``numpy_residual`` of
``test/core/test_egomotion.py``, written from the definition. Rows:

- ``residual``: one pair with the offset fit off (splat, masks, sums);
- ``residual + fit``: with the offset fit (the numpy side: one pass at the fitted offset, its
  fit not timed, so the ratio is a lower bound);
- ``prepare``: one frame's checks and edge mask (once per frame in a stream: each frame is
  the target of one pair and the source of the next); numpy: 4-neighbour jumps and a 3×3
  dilation by shifts;
- ``flicker (5 frames)``: a window of five frames with their left images, per frame (add)
  and the window's sums; numpy: ``numpy_flicker`` of the same test file (``std(ddof=1)`` over
  the stack, the same masks, the same per-cell sums).

The best and the median of ``--repeat`` runs of CPU time (``process_time``: a shared
machine's other work is not counted, its contention for the core is) are printed, with the
load average at the start; the process is pinned to one core and the kernels are serial (no
``prange``), so these are one-core numbers. The ratio is of the best times.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from dispeval_ros.core.egomotion import (
    EgoMotionOptions,
    FlickerWindow,
    PinholeCamera,
    TemporalSums,
    egomotion_residual,
    prepare_frame,
)
from dispeval_ros.testbed import driving_setup, driving_world_at, render_stereo
from dispeval_ros.testbed.scene import KITTI_HEIGHT, KITTI_WIDTH

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))  # bag_support, ...
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test" / "core"))
from test_egomotion import numpy_edges, numpy_flicker, numpy_residual

WINDOW = 5


def timed(run: Callable[[], object], repeat: int) -> tuple[float, float]:
    """The fastest and the median of ``repeat`` runs, in ms (after one warm-up run)."""
    run()
    times = []
    for _ in range(repeat):
        start = time.process_time()
        run()
        times.append(time.process_time() - start)
    return 1e3 * min(times), 1e3 * float(np.median(times))


def main() -> None:
    """Render two KITTI-size frames, check both implementations agree, time them."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=20, help="timed runs per case")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    world, rig = driving_setup(KITTI_WIDTH, KITTI_HEIGHT, 10.0, 0)
    frames, rigs = [], []
    for index in range(WINDOW):
        world_t, rig_t = driving_world_at(world, rig, index / 10.0)
        frames.append(render_stereo(world_t, rig_t, stamp=index / 10.0, noise_seed=[0, index]))
        rigs.append(rig_t)
    rng = np.random.default_rng(0)
    estimates = [f.gt_left + rng.normal(0, 0.2, f.gt_left.shape).astype(np.float32) for f in frames]
    camera = PinholeCamera(rig.camera, rig.cx, rig.cy)
    motion = np.eye(4)
    motion[2, 3] = rigs[1].position[2] - rigs[0].position[2]
    plain, fitted = EgoMotionOptions(fit_offset=False), EgoMotionOptions()
    source = prepare_frame(estimates[0], frames[0].left)
    target = prepare_frame(estimates[1], frames[1].left)

    result = egomotion_residual(source, target, motion, camera, options=plain, keep_maps=True)
    sums, status, _ = numpy_residual(source, target, motion, camera, plain, 0.0)
    if not (np.array_equal(status, result.maps[0]) and np.allclose(sums, result.sums)):
        raise SystemExit("the numba and numpy residuals differ")
    if not np.array_equal(numpy_edges(source.disparity, 2.0, 3), source.edges):
        raise SystemExit("the numba and numpy edge masks differ")
    offset = egomotion_residual(source, target, motion, camera, options=fitted).offsets[0]
    summary = result.summary("all")
    print(
        f"{KITTI_WIDTH}×{KITTI_HEIGHT}, estimate = exact disparity + N(0, 0.2 px), motion "
        f"{motion[2, 3]:.3f} m forward: {summary['n_residual']:.0f} of {summary['n']:.0f} px "
        f"counted, mean |r| {summary['mean_abs']:.3f} px, fitted offset {offset:+.4f} px"
    )

    window_frames = [prepare_frame(e, f.left) for e, f in zip(estimates, frames, strict=True)]

    def numba_flicker(keep_maps: bool = False) -> TemporalSums:
        window = FlickerWindow(camera.camera)
        for frame in window_frames:
            window.add(frame)
        return window.sums(keep_maps=keep_maps)

    spread = numba_flicker(keep_maps=True)
    numpy_sums, numpy_status, _ = numpy_flicker(window_frames, camera.camera, EgoMotionOptions())
    if not (
        np.array_equal(numpy_status, spread.maps[0])
        and np.allclose(numpy_sums, spread.sums, rtol=1e-5, atol=1e-4)
    ):
        raise SystemExit("the numba and numpy flicker differ")

    cases = [
        (
            "residual",
            lambda: egomotion_residual(source, target, motion, camera, options=plain),
            lambda: numpy_residual(source, target, motion, camera, plain, 0.0),
            1,
        ),
        (
            "residual + fit",
            lambda: egomotion_residual(source, target, motion, camera, options=fitted),
            lambda: numpy_residual(source, target, motion, camera, plain, offset),
            1,
        ),
        (
            "prepare",
            lambda: prepare_frame(estimates[0], frames[0].left),
            lambda: numpy_edges(np.where(estimates[0] > 0, estimates[0], np.nan), 2.0, 3),
            1,
        ),
        (
            f"flicker ({WINDOW} frames)",
            numba_flicker,
            lambda: numpy_flicker(window_frames, camera.camera, EgoMotionOptions()),
            WINDOW,
        ),
    ]
    load = " ".join(f"{value:.2f}" for value in os.getloadavg())
    print(f"one core, ms per frame (best / median of runs); load average {load}")
    print(f"{'':<24} {'numba':>15} {'numpy':>15} {'ratio':>7}")
    for name, fast, slow, per in cases:
        numba_best, numba_median = (value / per for value in timed(fast, args.repeat))
        numpy_best, numpy_median = (value / per for value in timed(slow, max(3, args.repeat // 4)))
        print(
            f"{name:<24} {numba_best:>7.2f} /{numba_median:>6.2f} {numpy_best:>7.2f} /"
            f"{numpy_median:>6.2f} {numpy_best / numba_best:>6.1f}×"
        )


if __name__ == "__main__":
    main()
