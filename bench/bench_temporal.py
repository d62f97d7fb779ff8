"""Pair measures (tepe, tepe_r, tepe_bmp, tepe_bad_X): the numba path against plain numpy.

Prints timings and ratios only (machines are noisy: nothing here is asserted). Run:

    python bench/bench_temporal.py [--repeat N]

Frames: two consecutive 1242×375 frames of the synthetic drive (dense exact GT) and OpenCV
StereoSGBM's estimates of both (so holes are real). Criteria all + visibility + depth (7);
measures tepe, tepe_r, tepe_bmp and tepe_bad_0.5/2/4. The numpy baseline scores the ``thesis``
policy (numpy has no KITTI interpolation to copy): a boolean mask per criterion, a numpy
expression per measure; both must agree. Timed apart: the GT side of a pair (frame t+1's GT
gathered in frame t's partition order, once per pair for every method) and the method side
(both estimates, per method and pair), under ``thesis`` and ``interpolate``: each estimate
gathered for each pair (two maps passed), and each frame's estimate prepared once
(``TemporalScorer.prepare``) for the two pairs it belongs to, the amortised per-pair cost being
one prepare plus the score of two prepared frames. Frame t's partition is the frame scoring's
own (built once per GT map whether or not pairs are scored). The process is pinned to one
core; the load average is printed.
"""

from __future__ import annotations

import argparse
import functools
import os

import numpy as np
from bench_scoring import MEASURES as FRAME_MEASURES  # this folder is on sys.path as a script
from bench_scoring import pin_to_one_core, timed

from dispeval_ros import Evaluator
from dispeval_ros.core.temporal import TemporalScorer
from dispeval_ros.testbed import default_methods, make_driving_sequence

CRITERIA = ("all", "visibility", "depth")
MEASURES = ("tepe", "tepe_r", "tepe_bmp", "tepe_bad_0.5", "tepe_bad_2", "tepe_bad_4")
THRESHOLDS = {"tepe_bmp": 1.0, "tepe_bad_0.5": 0.5, "tepe_bad_2": 2.0, "tepe_bad_4": 4.0}


def numpy_baseline(
    gt: np.ndarray,
    gt_next: np.ndarray,
    est: np.ndarray,
    est_next: np.ndarray,
    masks: dict[str, np.ndarray],
) -> dict[str, dict[str, float]]:
    """The straightforward way (``thesis`` policy: a missing estimate is E = 0)."""
    valid_next = np.isfinite(gt_next) & (gt_next > 0)
    value = np.where(np.isfinite(est) & (est > 0), est, 0.0)
    value_next = np.where(np.isfinite(est_next) & (est_next > 0), est_next, 0.0)
    results = {}
    for name, mask in masks.items():
        pixels = mask & valid_next
        change = gt[pixels].astype(np.float64) - gt_next[pixels].astype(np.float64)
        e = np.abs((value[pixels] - value_next[pixels].astype(np.float64)) - change)
        results[name] = {
            "tepe": float(np.mean(e)),
            "tepe_r": float(np.mean(e / (np.abs(change) + 1e-3))),
            **{m: 100.0 * float(np.mean(e > t)) for m, t in THRESHOLDS.items()},
        }
    return results


def main() -> None:
    """Time one 1242×375 frame pair."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--repeat", type=int, default=40, help="timed calls per measurement")
    args = parser.parse_args()
    pin_to_one_core()
    frames = list(make_driving_sequence(n_frames=2, width=1242, height=375, seed=3))
    sgbm = next(m for m in default_methods(1242) if m.name == "sgbm")
    gt, gt_next = frames[0].gt_left, frames[1].gt_left
    est, est_next = (sgbm.compute(f.left, f.right) for f in frames)

    thesis = Evaluator(CRITERIA, FRAME_MEASURES, missing="thesis")
    interpolating = Evaluator(CRITERIA, FRAME_MEASURES, missing="interpolate")
    reference = thesis.reference(gt, frames[0].camera)
    scorer = TemporalScorer(thesis, MEASURES)
    scorer_interp = TemporalScorer(interpolating, MEASURES)
    pair = scorer.pair(reference, gt_next)
    masks = {name: reference.partition.mask(name) for name in reference.partition.criteria}

    n = args.repeat
    t_numpy = timed(lambda: numpy_baseline(gt, gt_next, est, est_next, masks), max(3, n // 4))
    t_pair = timed(lambda: scorer.pair(reference, gt_next), n)
    t_thesis = timed(lambda: scorer.score(pair, est, est_next), n)
    t_interp = timed(lambda: scorer_interp.score(pair, est, est_next), n)
    t_frame = timed(lambda: thesis.score(reference, est), n)
    amortised = {}
    for policy, one in (("thesis", scorer), ("interpolate", scorer_interp)):
        ready, ready_next = one.prepare(est), one.prepare(est_next)
        assert one.score(pair, ready, ready_next).sums.tobytes() == (
            one.score(pair, est, est_next).sums.tobytes()
        ), policy
        t_prepare = timed(functools.partial(one.prepare, est), n)
        t_ready = timed(functools.partial(one.score, pair, ready, ready_next), n)
        amortised[policy] = (t_prepare, t_ready, t_prepare + t_ready)

    ours = scorer.score(pair, est, est_next)
    theirs = numpy_baseline(gt, gt_next, est, est_next, masks)
    worst = max(
        abs(ours[c][m] - theirs[c][m]) / max(abs(theirs[c][m]), 1e-12)
        for c in reference.partition.criteria
        for m in MEASURES
        if ours[c]["n_pair"] > 0
    )
    both = t_pair + t_thesis
    load = " ".join(f"{value:.2f}" for value in os.getloadavg())
    print(f"dispeval_ros pair-measure benchmark (one core; median of {n}; load {load})")
    print(
        f"\n1242×375 synthetic drive, frames 0→1, SGBM: {int(ours['all']['n_pair'])} pixel "
        f"pairs with GT in both frames, {len(reference.partition.criteria)} criteria"
    )
    print(f"  numpy baseline, thesis policy            {t_numpy:8.2f} ms   1.0×")
    print(
        f"  GT side of a pair (once per pair)        {t_pair:8.2f} ms"
        f"\n  method side, thesis policy               {t_thesis:8.2f} ms   "
        f"{t_numpy / t_thesis:5.1f}× faster"
        f"\n  method side, interpolate (default)       {t_interp:8.2f} ms   "
        f"{t_numpy / t_interp:5.1f}× faster"
        f"\n  GT + method side, thesis (one method)    {both:8.2f} ms   "
        f"{t_numpy / both:5.1f}× faster"
    )
    print("  each frame prepared once (a sequence: one prepare per pair, amortised):")
    for policy, (t_prepare, t_ready, t_total) in amortised.items():
        print(
            f"    {policy + ':':12s} prepare {t_prepare:5.2f} ms per frame + score "
            f"{t_ready:5.2f} ms = {t_total:8.2f} ms per pair   {t_numpy / t_total:5.1f}× faster"
        )
    print(f"  (frame scoring of one estimate, thesis  {t_frame:8.2f} ms, bench_scoring's measures)")
    print(f"  largest relative difference numba vs numpy: {worst:.2e}")


if __name__ == "__main__":
    main()
