"""KITTI 2012 devkit (``evaluate_stereo.cpp``) Out-k and Avg, exactly.

``e`` in float32, the error sum in a float32 in column-major order (``u`` outer, ``v``
inner), the summary a float32 mean of per-frame values (``statMean``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dispeval_ros.core.protocols.common import (
    OFFICIAL,
    Arithmetic,
    FrameData,
    FrameResult,
    Protocol,
)
from dispeval_ros.core.protocols.kitti import (
    _KITTI_INTERPOLATION,
    KITTI_RESULTS,
    _kitti_columns,
    _KittiFrame,
)

_OUT = tuple(f"Out-{k}" for k in (2, 3, 4, 5))


def kitti2012_frame(
    frame: str,
    gt_occ: np.ndarray,
    gt_noc: np.ndarray | None,
    estimate: np.ndarray,
    arithmetic: Arithmetic = OFFICIAL,
) -> FrameResult:
    """Out-2…5 and Avg per region, over all GT pixels and over estimated ones, density."""
    prepared = _KittiFrame.of(frame, gt_occ, gt_noc, estimate, "disp_noc")
    for region, gt in prepared.grounds:
        prepared.result.values[region] = _kitti2012_region(
            gt, prepared.interpolated, prepared.has_estimate, arithmetic
        )
    return prepared.result


def _kitti2012_region(
    gt: np.ndarray, interpolated: np.ndarray, has_estimate: np.ndarray, arithmetic: Arithmetic
) -> dict[str, float]:
    valid = gt > 0
    real = arithmetic.real
    error = np.abs(gt.astype(real) - interpolated.astype(real)).astype(real)
    # the devkit loops u (columns) outside, v (rows) inside: transpose for that order
    by_column = error.T[valid.T]
    by_column_est = error.T[(valid & has_estimate).T]
    n, n_est = by_column.size, by_column_est.size
    ratio = arithmetic.ratio
    values: dict[str, float] = {}
    for k in (2, 3, 4, 5):
        values[f"Out-{k}"] = 100.0 * ratio(int(np.count_nonzero(by_column > real(k))), n)
    values["Avg"] = float(arithmetic.accumulate(by_column) / max(real(n), real(1.0)))
    for k in (2, 3, 4, 5):
        # the devkit leaves the counts unnormalised when no pixel has an estimate
        count = int(np.count_nonzero(by_column_est > real(k)))
        values[f"Out-{k} (est)"] = 100.0 * (ratio(count, n_est) if n_est else float(count))
    values["Avg (est)"] = float(arithmetic.accumulate(by_column_est) / max(real(n_est), real(1.0)))
    values["density"] = 100.0 * ratio(n_est, n)
    return {column: values[column] for column in KITTI2012.columns}


def kitti2012_summary(
    frames: Sequence[FrameResult], arithmetic: Arithmetic = OFFICIAL
) -> dict[str, dict[str, float]]:
    """``statMean``: per column, the float32 sum of the per-frame values over float32(count)."""
    summary: dict[str, dict[str, float]] = {}
    real = arithmetic.real
    for region in KITTI2012.regions:
        rows = [f.values[region] for f in frames if region in f.values]
        if not rows:
            continue
        summary[region] = {}
        for column in KITTI2012.columns:
            # the devkit averages fractions; the percent scale is applied after
            scale = 100.0 if column in KITTI2012.percent else 1.0
            terms = np.array([real(row[column] / scale) for row in rows], dtype=real)
            mean = arithmetic.accumulate(terms) / real(len(rows))
            summary[region][column] = scale * float(mean)
    return summary


def _frame(data: FrameData, estimate: np.ndarray, arithmetic: Arithmetic) -> FrameResult:
    return kitti2012_frame(data.frame, data.gt, data.gt_noc, estimate, arithmetic)


KITTI2012 = Protocol(
    name="kitti2012",
    title="KITTI 2012 stereo",
    tool="KITTI 2012 devkit evaluate_stereo (disparityErrorsOutlier/Average)",
    regions=("noc", "occ"),
    columns=_kitti_columns((*_OUT, "Avg")),
    percent=tuple(c for c in _kitti_columns((*_OUT, "Avg")) if not c.startswith("Avg")),
    objectives=(*_OUT, "Avg"),
    summary="float32 mean of the per-frame values (statMean)",
    float32="e in float32, the error sum in float32 in column-major order, the means in float32",
    settings={"thresholds": [2, 3, 4, 5], "interpolation": _KITTI_INTERPOLATION},
    frame_function=_frame,
    summary_function=kitti2012_summary,
    results=KITTI_RESULTS,
)
