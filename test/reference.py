"""Independent re-computations of the scoring definitions, for the tests to check against.

Plain numpy written from METHOD.md / docs/method.md, never calling dispeval_ros scoring code
(only its ``Camera`` record and ``Scores`` container are read), so that a library defect cannot
hide in its own reference. The conventions they implement (METHOD.md §1–3):

Conventions of the code under test that these tests rely on (METHOD.md §1–3):

- valid GT = finite and > 0, restricted to an official ``all`` mask when one is given;
- missing estimate = not finite, ≤ 0, or outside ``est_range`` (inclusive ``[lo, hi]``);
- ``interpolate`` = KITTI background interpolation (a gap between two valid estimates of a row
  takes the smaller neighbour, a leading gap the first valid value, a trailing gap the last;
  rows above the first / below the last row with any valid value copy that row; still
  missing → E = 0), ``thesis`` = E = 0 for missing, ``ignore`` = missing points left out of
  every error measure but counted in ``n`` and ``density``;
- per criterion: ``n`` = valid-GT points, ``density`` = valid estimates (before interpolation)
  / n, N_eval = n except under ``ignore`` (number of valid estimates); bmp/bad_X/d1 are
  percentages of N_eval; mae, mse, rmse, mre are means over N_eval; sze and bmpre are sums,
  sze_mean and bmpre_mean these sums / N_eval; aNN = sorted errors at index ⌊N_eval·q/100⌋;
- errors are computed in float64 from the float32 maps: ``e = |float64(E) − float64(D)|``;
- SZE = Σ|f·B/(D + doffs + μ) − f·B/(E + doffs + μ)| (f·B = 1, doffs = 0 without a camera,
  flagged ``scores.relative``);
- visibility: occluded from the official ``nonocc`` mask, else a left-right check with the
  right GT, else z-buffer forward warping (target column ``floor(x − d + 0.5)``, i.e. round
  half up); boundary = the ``disc`` mask, else points within a ``width`` square of a
  4-neighbour jump > ``gap`` between two valid points, minus occluded; interior = the rest;
- depth: deterministic 3-means (Lloyd to a fixed point, started from the optimal split of a
  fine histogram; a value equal to a threshold goes to the farther cluster), ``near`` =
  largest disparities; metric ranges are half-open ``[from, to)`` in depth ``Z = f·B/(d + doffs)``.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.measures import Scores

POLICIES = ("interpolate", "thesis", "ignore")
"""The missing-estimate policies, in the order the tests parametrize them."""
SUMS = ("mae", "mse", "rmse", "mre", "sze", "sze_mean", "bmpre", "bmpre_mean")
"""Measures that are sums or means of float terms: compared with rtol 1e-6 (others 1e-9)."""

# ------------------------------------------------------------------ missing estimates


def kitti_fill(est: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """KITTI background interpolation, written with index arithmetic (no loops over gaps).

    Returns float64 values to score; points that stay missing are 0.
    """
    height, width = est.shape
    columns = np.broadcast_to(np.arange(width), est.shape)
    previous = np.maximum.accumulate(np.where(valid, columns, -1), axis=1)
    following = np.minimum.accumulate(np.where(valid, columns, width)[:, ::-1], axis=1)[:, ::-1]
    rows = np.arange(height)[:, None]
    left = np.where(previous >= 0, est[rows, np.clip(previous, 0, width - 1)], np.nan)
    right = np.where(following < width, est[rows, np.clip(following, 0, width - 1)], np.nan)
    filled = np.where(valid, est, np.fmin(left, right))  # fmin: one side missing → the other
    filled = np.where(np.isnan(filled), 0.0, filled)
    with_values = np.flatnonzero(valid.any(axis=1))
    if with_values.size:
        filled[: with_values[0]] = filled[with_values[0]]
        filled[with_values[-1] + 1 :] = filled[with_values[-1]]
    return filled


def kitti_devkit_interpolation(disparity: np.ndarray) -> np.ndarray:
    """A line-by-line port of the KITTI devkit's ``interpolateBackground`` (io_disp.h).

    Invalid = ≤ 0 or not finite. Row pass: a gap with valid pixels on both sides takes the
    smaller of them; then extrapolation to the left and right of each row; then per column,
    to the top and bottom. Pixels still invalid are returned as 0.
    """
    d = np.where(np.isfinite(disparity) & (disparity > 0), disparity, -1.0).astype(np.float64)
    height, width = d.shape
    for v in range(height):
        row = d[v]
        valid = np.flatnonzero(row > 0)
        if valid.size == 0:
            continue
        for a, b in itertools.pairwise(valid):
            if b > a + 1:
                row[a + 1 : b] = min(row[a], row[b])
        row[: valid[0]] = row[valid[0]]
        row[valid[-1] + 1 :] = row[valid[-1]]
    for u in range(width):
        column = d[:, u]
        valid = np.flatnonzero(column > 0)
        if valid.size == 0:
            continue
        column[: valid[0]] = column[valid[0]]
        column[valid[-1] + 1 :] = column[valid[-1]]
    return np.where(d > 0, d, 0.0)


def scored_estimate(est: np.ndarray, policy: str) -> tuple[np.ndarray, np.ndarray]:
    """(value to score, whether the pixel takes part) per pixel under a missing policy."""
    valid = np.isfinite(est) & (est > 0)
    if policy == "interpolate":
        return kitti_devkit_interpolation(est), np.ones(est.shape, bool)
    values = np.where(valid, est, 0.0).astype(np.float64)
    return values, valid if policy == "ignore" else np.ones(est.shape, bool)


def valid_of(gt: np.ndarray, masks: dict | None = None) -> np.ndarray:
    """Valid GT: finite and > 0, within the official ``all`` mask when there is one."""
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(gt) & (gt > 0)
    if masks and "all" in masks:
        valid &= masks["all"]
    return valid


# ------------------------------------------------------------------------------ measures


def numpy_measures(
    gt: np.ndarray,
    est: np.ndarray,
    criteria: dict[str, np.ndarray],
    policy: str,
    camera: Camera | None = None,
    est_range: tuple[float, float] | None = None,
    delta: float = 1.0,
    mu: float = 0.01,
) -> dict[str, dict[str, float]]:
    """Every default measure per criterion (a boolean mask each), straight from METHOD.md §3."""
    d = np.asarray(gt, np.float32).astype(np.float64)
    raw = np.asarray(est, np.float32).astype(np.float64)
    lo, hi = est_range if est_range is not None else (-math.inf, math.inf)
    with np.errstate(invalid="ignore"):
        est_valid = np.isfinite(raw) & (raw > 0) & (raw >= lo) & (raw <= hi)
    if policy == "interpolate":
        used = kitti_fill(np.where(est_valid, raw, 0.0), est_valid)
    else:
        used = np.where(est_valid, raw, 0.0)
    fb = camera.f * camera.baseline if camera else 1.0
    doffs = camera.doffs if camera else 0.0
    result: dict[str, dict[str, float]] = {}
    for name, mask in criteria.items():
        n = int(mask.sum())
        evaluated = mask & est_valid if policy == "ignore" else mask
        D = d[evaluated]
        E = used[evaluated]
        e = np.abs(E - D)
        count = e.size

        def ratio(x: float, count: int = count) -> float:
            return x / count if count else math.nan

        sze = float(np.abs(fb / (D + doffs + mu) - fb / (E + doffs + mu)).sum())
        bmpre = float((e / D)[e > delta].sum())
        values = {
            "n": float(n),
            "bmp": ratio(100.0 * np.count_nonzero(e > delta)),
            "bmp_count": float(np.count_nonzero(e > delta)),
            "bad_0.5": ratio(100.0 * np.count_nonzero(e > 0.5)),
            "bad_2": ratio(100.0 * np.count_nonzero(e > 2.0)),
            "bad_4": ratio(100.0 * np.count_nonzero(e > 4.0)),
            "mae": ratio(e.sum()),
            "mse": ratio((e * e).sum()),
            "rmse": math.sqrt(ratio((e * e).sum())),
            "mre": ratio((e / D).sum()),
            "sze": sze,
            "sze_mean": ratio(sze),
            "bmpre": bmpre,
            "bmpre_mean": ratio(bmpre),
            "d1": ratio(100.0 * np.count_nonzero((e > 3.0) & (e > 0.05 * D))),
            "density": float(est_valid[mask].sum()) / n if n else math.nan,
        }
        ordered = np.sort(e)
        for q in (50, 90, 95, 99):
            values[f"a{q}"] = float(ordered[(count * q) // 100]) if count else math.nan
        result[name] = values
    return result


def assert_matches(scores: Scores, expected: dict[str, dict[str, float]]) -> None:
    """Library scores equal the re-computation: rtol 1e-9 for counts/percentages, 1e-6 sums."""
    for criterion, values in expected.items():
        got = scores[criterion]
        for measure, want in values.items():
            have = float(got[measure])
            where = f"{criterion}/{measure} ({scores.policy}): library {have!r}, numpy {want!r}"
            if math.isnan(want):
                assert math.isnan(have), where
                continue
            rel = 1e-6 if measure in SUMS else 1e-9
            # a tiny absolute tolerance: terms that are 0 in exact arithmetic (E = D) may come
            # out as ±1 ulp from the compiled kernel's reciprocal arithmetic
            assert math.isclose(have, want, rel_tol=rel, abs_tol=1e-9), where


# ------------------------------------------------------------------------------ criteria


def zbuffer_occlusion(gt: np.ndarray, valid: np.ndarray, tolerance: float = 1.0) -> np.ndarray:
    """Straightforward numpy z-buffer: per row, the largest disparity landing on each column."""
    height, width = gt.shape
    d = np.where(valid, gt, 0.0).astype(np.float64)
    target = np.floor(np.arange(width)[None, :] - d + 0.5).astype(np.int64)
    inside = valid & (target >= 0) & (target < width)
    flat = (np.arange(height)[:, None] * width + np.clip(target, 0, width - 1)).ravel()
    zbuffer = np.full(height * width, -np.inf)
    np.maximum.at(zbuffer, flat[inside.ravel()], d.ravel()[inside.ravel()])
    hidden = zbuffer[flat].reshape(gt.shape) > d + tolerance
    return valid & (~inside | hidden)


def left_right_occlusion(gt: np.ndarray, right: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """MiddEval3's check: |D_L − D_R(t)| > 1, t = C round(x − D_L) outside, or D_R(t) unknown."""
    width = gt.shape[1]
    ys, xs = np.nonzero(valid)
    d = gt[ys, xs].astype(np.float64)
    shift = xs - d
    target = (np.sign(shift) * np.floor(np.abs(shift) + 0.5)).astype(np.int64)  # C round
    inside = (target >= 0) & (target < width)
    seen = right[ys, np.clip(target, 0, width - 1)].astype(np.float64)
    known = np.isfinite(seen) & (seen > 0)
    occluded = np.zeros(gt.shape, bool)
    occluded[ys, xs] = ~inside | ~known | (np.abs(d - np.where(known, seen, 0.0)) > 1.0)
    return occluded


def near_jumps(gt: np.ndarray, valid: np.ndarray, gap: float = 2.0, width: int = 9) -> np.ndarray:
    """Within a width×width square of a 4-neighbour jump > gap between two valid points."""
    d = np.where(valid, gt, 0.0).astype(np.float64)
    jump = np.zeros(gt.shape, bool)
    horizontal = valid[:, 1:] & valid[:, :-1] & (np.abs(np.diff(d, axis=1)) > gap)
    vertical = valid[1:] & valid[:-1] & (np.abs(np.diff(d, axis=0)) > gap)
    jump[:, 1:] |= horizontal
    jump[:, :-1] |= horizontal
    jump[1:] |= vertical
    jump[:-1] |= vertical
    # square dilation as a 2-D prefix sum: any jump inside the window
    size = width
    r = size // 2
    padded = np.pad(jump.astype(np.int64), ((r + 1, r), (r + 1, r)))
    table = padded.cumsum(0).cumsum(1)
    h, w = gt.shape
    window = (
        table[size:, size:][:h, :w]
        - table[:-size, size:][:h, :w]
        - table[size:, :-size][:h, :w]
        + table[:-size, :-size][:h, :w]
    )
    return window > 0


def plain_lloyd(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lloyd's 3-means on exact values from 1/6, 1/2, 5/6 of the range (ties to the lower)."""
    v = values.astype(np.float64)
    lo, hi = v.min(), v.max()
    centroids = np.array([lo + (hi - lo) / 6, lo + (hi - lo) / 2, lo + 5 * (hi - lo) / 6])
    for _ in range(1000):
        low, high = (centroids[:2] + centroids[1:]) / 2
        labels = np.where(v <= low, 0, np.where(v <= high, 1, 2))
        updated = np.array(
            [v[labels == k].mean() if (labels == k).any() else centroids[k] for k in range(3)]
        )
        if np.array_equal(updated, centroids):
            break
        centroids = updated
    return labels, centroids


def optimal_three_clustering(values: np.ndarray) -> tuple[float, tuple[float, float]]:
    """Global optimum of 1-D 3-clustering (least squares) by trying every pair of cuts.

    Optimal 1-D clusters are intervals of the sorted distinct values, so with k distinct
    values there are (k−1)(k−2)/2 candidates: few for 8-bit Middlebury GT.
    """
    distinct, weight = np.unique(values.astype(np.float64), return_counts=True)
    cw = np.concatenate([[0.0], np.cumsum(weight)])
    cs = np.concatenate([[0.0], np.cumsum(weight * distinct)])
    cq = np.concatenate([[0.0], np.cumsum(weight * distinct**2)])

    def sse(a: np.ndarray | int, b: np.ndarray | int) -> np.ndarray:
        return (cq[b] - cq[a]) - (cs[b] - cs[a]) ** 2 / (cw[b] - cw[a])

    k = distinct.size
    i, j = np.triu_indices(k, 1)  # first cluster [0, i), second [i, j), third [j, k)
    keep = i >= 1
    i, j = i[keep], j[keep]
    total = sse(0, i) + sse(i, j) + sse(j, k)
    best = int(np.argmin(total))
    return float(total[best]), (float(distinct[i[best] - 1]), float(distinct[j[best] - 1]))


def within_cluster_sse(values: np.ndarray, labels: list[np.ndarray]) -> float:
    """Sum of squared distances to each cluster's mean (the 3-means objective)."""
    return float(sum(((values[m] - values[m].mean()) ** 2).sum() for m in labels if m.any()))
