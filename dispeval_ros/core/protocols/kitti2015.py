"""KITTI 2015 devkit (``evaluate_scene_flow.cpp``) D1 outliers, exactly.

``e = |d_gt − d_ipol|`` and ``e/|d_gt|`` in float32, the quotient compared with the double
``0.05`` (so an error of exactly 5 % is an outlier); per-frame ratios in float32; pooled
counters summed in float32 (they exceed 2²⁴), which is why frames keep their raw counters.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from dispeval_ros.core.protocols.common import (
    OFFICIAL,
    Arithmetic,
    FrameData,
    FrameResult,
    Protocol,
    _same_shape,
)
from dispeval_ros.core.protocols.kitti import (
    _KITTI_INTERPOLATION,
    KITTI_RESULTS,
    _kitti_columns,
    _KittiFrame,
)

_D1 = ("D1-bg", "D1-fg", "D1-all")

_D1_COUNTERS = ("bg", "fg", "all")


def kitti2015_frame(
    frame: str,
    gt_occ: np.ndarray,
    gt_noc: np.ndarray | None,
    estimate: np.ndarray,
    obj_map: np.ndarray | None,
    arithmetic: Arithmetic = OFFICIAL,
) -> FrameResult:
    """D1 per region (``noc`` from ``disp_noc_0``, ``occ`` from ``disp_occ_0``), frame values."""
    prepared = _KittiFrame.of(frame, gt_occ, gt_noc, estimate, "disp_noc_0")
    result = prepared.result
    foreground = None
    if obj_map is not None:
        _same_shape(prepared.grounds[-1][1], np.asarray(obj_map), "the object map (obj_map)")
        foreground = np.asarray(obj_map) > 0
    else:
        result.notes.append("D1-bg/D1-fg: no obj_map (every pixel counted as background)")
    for region, gt in prepared.grounds:
        counts = _d1_counts(
            gt, prepared.interpolated, prepared.has_estimate, foreground, arithmetic
        )
        result.counts[region] = counts
        result.values[region] = kitti2015_values(counts, foreground is not None, arithmetic)
    return result


def _d1_counts(
    gt: np.ndarray,
    interpolated: np.ndarray,
    has_estimate: np.ndarray,
    foreground: np.ndarray | None,
    arithmetic: Arithmetic,
) -> list[float]:
    """The devkit's 12 counters: (errors, pixels, errors est, pixels est) × (bg, fg, all)."""
    valid = gt > 0
    real = arithmetic.real
    error = np.abs(gt.astype(real) - interpolated.astype(real)).astype(real)
    with np.errstate(divide="ignore", invalid="ignore"):
        relative = (error / np.abs(gt.astype(real))).astype(real)
        outlier = valid & (error > 3.0) & (relative.astype(np.float64) > 0.05)
    fg = np.zeros(gt.shape, bool) if foreground is None else foreground
    counts: list[float] = []
    for part in (valid & ~fg, valid & fg, valid):
        counts += [
            int(np.count_nonzero(outlier & part)),
            int(np.count_nonzero(part)),
            int(np.count_nonzero(outlier & part & has_estimate)),
            int(np.count_nonzero(part & has_estimate)),
        ]
    return counts


def kitti2015_values(
    counts: Sequence[float], with_foreground: bool = True, arithmetic: Arithmetic = OFFICIAL
) -> dict[str, float]:
    """D1 columns (percent) from the 12 counters, with the devkit's float32 ratios."""
    values: dict[str, float] = {}
    ratio = arithmetic.ratio
    for index, part in enumerate(_D1_COUNTERS):
        errors, pixels, errors_est, pixels_est = counts[4 * index : 4 * index + 4]
        unknown = part != "all" and not with_foreground
        values[f"D1-{part}"] = math.nan if unknown else 100.0 * ratio(errors, pixels)
        values[f"D1-{part} (est)"] = math.nan if unknown else 100.0 * ratio(errors_est, pixels_est)
    values["density"] = 100.0 * ratio(counts[11], counts[9])
    return {column: values[column] for column in KITTI2015.columns}


def kitti2015_summary(
    frames: Sequence[FrameResult], arithmetic: Arithmetic = OFFICIAL
) -> dict[str, dict[str, float]]:
    """Pooled D1: the counters of every frame summed in float32 accumulators, in frame order."""
    summary: dict[str, dict[str, float]] = {}
    with_foreground = all("D1-bg/D1-fg" not in " ".join(f.notes) for f in frames)
    for region in KITTI2015.regions:
        parts = [f.counts[region] for f in frames if region in f.counts]
        if not parts:
            continue
        real = arithmetic.real
        totals = np.zeros(12, dtype=real)
        for counts in parts:
            totals = (totals + np.asarray(counts, dtype=real)).astype(real)
        summary[region] = kitti2015_values([float(v) for v in totals], with_foreground, arithmetic)
    return summary


def _frame(data: FrameData, estimate: np.ndarray, arithmetic: Arithmetic) -> FrameResult:
    return kitti2015_frame(data.frame, data.gt, data.gt_noc, estimate, data.obj_map, arithmetic)


KITTI2015 = Protocol(
    name="kitti2015",
    title="KITTI 2015 stereo",
    tool="KITTI 2015 devkit evaluate_scene_flow (disparityErrorsOutlier)",
    regions=("noc", "occ"),
    columns=_kitti_columns(_D1),
    percent=_kitti_columns(_D1),
    objectives=_D1,
    summary="pooled counts over frames (float32 accumulators, as the devkit)",
    float32="e and e/|d| in float32 (compared with the double 0.05), ratios and pooled "
    "counters in float32",
    settings={
        "abs_thresh": 3.0,
        "rel_thresh": 0.05,
        "interpolation": _KITTI_INTERPOLATION,
        "foreground": "obj_map > 0",
    },
    frame_function=_frame,
    summary_function=kitti2015_summary,
    results=KITTI_RESULTS,
)
