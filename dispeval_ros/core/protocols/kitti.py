"""What the KITTI 2015 and KITTI 2012 devkits share: columns and background interpolation.

KITTI's ``interpolateBackground`` leaves rows without any estimate between estimated rows at
−1 (and the whole map when nothing is estimated); :func:`kitti_interpolation` does the same,
because both devkits score the interpolated map.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dispeval_ros.core import kernels
from dispeval_ros.core.evaluator import as_disparity
from dispeval_ros.core.protocols.common import F32, FrameResult, ResultLayout, _same_shape

_KITTI_INTERPOLATION = "devkit interpolateBackground (rows without estimate stay -1)"
#: A KITTI submission's ``disp_0/`` (or the devkit's ``data/``), or the PNGs themselves; never
#: in the GT tree, and only the 16-bit PNGs the devkits read.
KITTI_RESULTS = ResultLayout(
    folder=("disp_0/{frame}.png", "data/{frame}.png", "{frame}.png"), scene=(), encoding="png16"
)


def _kitti_columns(main: tuple[str, ...]) -> tuple[str, ...]:
    """KITTI's columns: each over all GT pixels, then over estimated pixels (est), density."""
    return (*main, *(f"{c} (est)" for c in main), "density")


def kitti_interpolation(estimate: np.ndarray) -> np.ndarray:
    """The KITTI devkits' ``interpolateBackground`` of an estimate (invalid: not finite or ≤ 0).

    Per row, gaps between two valid pixels take the smaller of the two, then the row is
    extended to both ends; per column, the first and last filled rows are copied upwards and
    downwards. A row with no valid pixel between filled rows stays −1, as in the devkit.
    """
    estimate = np.ascontiguousarray(estimate, dtype=F32)
    coded = np.empty_like(estimate)
    kernels.normalise_estimate(
        estimate, kernels.POSITIVE, math.inf, 0.0, 0.0, kernels.POLICY_INTERPOLATE, coded
    )
    filled = np.abs(coded)
    with np.errstate(invalid="ignore"):
        has_valid = (np.isfinite(estimate) & (estimate > 0)).any(axis=1)
    rows = np.flatnonzero(has_valid)
    if rows.size == 0:
        filled[:] = -1.0
        return filled
    inner = np.zeros(estimate.shape[0], bool)
    inner[rows[0] : rows[-1] + 1] = True
    filled[inner & ~has_valid] = -1.0
    return filled


def _estimate_valid(estimate: np.ndarray) -> np.ndarray:
    """KITTI: an estimate is valid when its PNG value is > 0 (finite and > 0 here)."""
    with np.errstate(invalid="ignore"):
        return np.isfinite(estimate) & (estimate > 0)


@dataclass
class _KittiFrame:
    """What both KITTI devkits prepare: the GT maps present, the interpolated estimate."""

    result: FrameResult
    grounds: list[tuple[str, np.ndarray]]
    interpolated: np.ndarray
    has_estimate: np.ndarray

    @classmethod
    def of(
        cls,
        frame: str,
        gt_occ: np.ndarray,
        gt_noc: np.ndarray | None,
        estimate: np.ndarray,
        noc_name: str,
    ) -> _KittiFrame:
        occ = as_disparity(gt_occ, "the ground truth")
        estimate = as_disparity(estimate, "the estimate")
        _same_shape(occ, estimate, "the estimate")
        result = FrameResult(frame, {})
        grounds = []
        if gt_noc is None:
            result.notes.append(f"noc: no {noc_name} ground truth")
        else:
            noc = as_disparity(gt_noc, "the noc ground truth")
            _same_shape(occ, noc, "the noc ground truth")
            grounds.append(("noc", noc))
        grounds.append(("occ", occ))
        return cls(result, grounds, kitti_interpolation(estimate), _estimate_valid(estimate))
