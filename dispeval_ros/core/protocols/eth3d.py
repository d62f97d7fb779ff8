"""ETH3D two-view evaluation (``ComputeMetrics``), exactly.

``e = d − gt`` in float32, sums in double of float32 terms, the quantile index
``floor(N·q)`` with ``N·q`` in float32, ``rms = sqrtf(…)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from dispeval_ros.core.evaluator import as_disparity
from dispeval_ros.core.masks import inside_mask
from dispeval_ros.core.protocols.common import (
    _BAD,
    _BAD_COLUMNS,
    _QUANTILES,
    OFFICIAL,
    Arithmetic,
    FrameData,
    FrameResult,
    Protocol,
    ResultLayout,
    _error_columns,
    _same_shape,
    _weighted_mean,
    double_summary,
    float64_sum,
)


def eth3d_frame(
    frame: str,
    gt: np.ndarray,
    estimate: np.ndarray,
    nonocc: np.ndarray | None,
    arithmetic: Arithmetic = OFFICIAL,
) -> FrameResult:
    """ETH3D ``ComputeMetrics`` for ``nonocc`` (mask value 255) and ``all`` (finite GT)."""
    gt = as_disparity(gt, "the ground truth")
    estimate = as_disparity(estimate, "the estimate")
    _same_shape(gt, estimate, "the estimate")
    width = gt.shape[1]
    known = np.isfinite(gt)
    with np.errstate(invalid="ignore"):
        estimated = np.isfinite(estimate) & (estimate <= width) & (estimate >= -width)
        real = arithmetic.real
        signed = (estimate.astype(real) - gt.astype(real)).astype(real)
    result = FrameResult(frame, {})
    regions: dict[str, np.ndarray] = {}
    if nonocc is not None:
        _same_shape(gt, np.asarray(nonocc), "the nonocc mask (mask0nocc.png)")
        regions["nonocc"] = known & inside_mask("the nonocc mask (mask0nocc.png)", nonocc)
    else:
        result.notes.append("nonocc: no mask0nocc.png")
    regions["all"] = known
    for region, where in regions.items():
        result.values[region] = _eth3d_region(
            signed[where & estimated], int(np.count_nonzero(where)), arithmetic
        )
    return result


def _eth3d_region(signed: np.ndarray, n_gt: int, arithmetic: Arithmetic) -> dict[str, float]:
    size = signed.size
    values: dict[str, float] = {}
    if size == 0:
        values.update({f"bad {t:.1f}": 100.0 for t in _BAD})
        values.update({"avgerr": math.inf, "rms": math.inf})
        values.update({f"A{q}": math.inf for q in _QUANTILES})
        values["coverage"] = 0.0 if n_gt else math.nan
        return values
    real = arithmetic.real
    absolute = np.abs(signed).astype(real)
    for threshold in _BAD:
        values[f"bad {threshold:.1f}"] = (
            100.0 * int(np.count_nonzero(absolute > real(threshold))) / size
        )
    values["avgerr"] = float64_sum(absolute) / size
    squared = (signed * signed).astype(real)
    values["rms"] = arithmetic.root(float64_sum(squared) / size)
    ordered = np.sort(absolute)
    for q in _QUANTILES:
        values[f"A{q}"] = float(ordered[arithmetic.index(size, q)])
    values["coverage"] = 100.0 * (1.0 if size == n_gt else size / n_gt)
    return values


def eth3d_summary(frames: Sequence[FrameResult]) -> dict[str, dict[str, float]]:
    """Mean of every column over the frames."""
    return _weighted_mean(frames, [1.0] * len(frames))


#: An ETH3D submission holds ``<scene>.pfm`` per scene. Never ``<scene>/disp0.pfm``: that is
#: the GT's name in the two-view trees :func:`dispeval_ros.io.benchmarks.discover` accepts.
ETH3D_RESULTS = ResultLayout(
    folder=("{frame}.pfm", "{frame}/disp0{method}.pfm"),
    scene=("disp0{method}.pfm",),
    encoding="pfm",
)


def _frame(data: FrameData, estimate: np.ndarray, arithmetic: Arithmetic) -> FrameResult:
    return eth3d_frame(data.frame, data.gt, estimate, data.nonocc_mask, arithmetic)


ETH3D = Protocol(
    name="eth3d",
    title="ETH3D two-view",
    tool="ETH3D two-view-evaluation (ComputeMetrics)",
    regions=("nonocc", "all"),
    columns=(*_error_columns("avgerr"), "coverage"),
    percent=(*_BAD_COLUMNS, "coverage"),
    objectives=_error_columns("avgerr"),
    summary="mean of the per-frame values",
    float32="e = d - gt in float32, squared errors in float32 summed in double, "
    "rms = sqrtf, quantile index floor(float32(N) * q_f)",
    settings={
        "bad_thresholds": list(_BAD),
        "estimate_valid": "finite and -width <= d <= width",
        "gt_valid": "finite",
        "measures_over": "pixels with an estimate",
    },
    frame_function=_frame,
    summary_function=double_summary(eth3d_summary),
    results=ETH3D_RESULTS,
)
