"""The ``visibility`` and ``legacy`` sets: occlusion and depth-discontinuity masks of the GT.

Occlusion comes from an official mask, a left-right check or a z-buffer of the left GT;
boundaries from 4-neighbour jumps (dense GT) or a max/min filter (sparse GT such as LiDAR),
because a scan's points rarely have the neighbours a jump needs.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from dispeval_ros.core import kernels
from dispeval_ros.core.criteria.base import (
    LEGACY,
    VISIBILITY,
    CriterionSet,
    _check_shape,
    _flat,
    _partitioning,
)
from dispeval_ros.core.masks import inside_mask


def occlusion(
    gt: np.ndarray,
    valid: np.ndarray,
    *,
    nonocc: np.ndarray | None = None,
    gt_right: np.ndarray | None = None,
    tolerance: float = 1.0,
) -> tuple[np.ndarray, str]:
    """Occluded valid points and where that knowledge came from.

    In order of preference: an official non-occlusion mask, a left-right check against the
    right-view GT as MiddEval3's ``computemask`` does it (``|D_L(x,y) − D_R(t, y)| > 1`` with
    ``t = round(x − D_L)`` rounding halves away from zero, the target outside the image, or an
    unknown right-view value), or z-buffer forward warping of the left GT alone.
    """
    if nonocc is not None:
        _check_shape("the 'nonocc' mask", nonocc, gt)
        return valid & ~inside_mask("the 'nonocc' mask", nonocc), "official mask"
    if gt_right is not None:
        _check_shape("the right-view ground truth", gt_right, gt)
        occluded = kernels.left_right_occlusion(
            np.ascontiguousarray(gt, dtype=np.float32),
            np.ascontiguousarray(gt_right, dtype=np.float32),
            np.ascontiguousarray(valid, dtype=np.bool_),
        )
        return occluded, "right-view GT"
    if tolerance < 0:  # every point hides itself: the z-buffer of its own landing exceeds d + tol
        return valid.astype(np.bool_, copy=True), "left GT z-buffer"
    width = gt.shape[1]
    occluded = np.empty(gt.shape, dtype=np.bool_)
    kernels.forward_warp_occlusion(
        np.ascontiguousarray(gt, dtype=np.float32),
        np.ascontiguousarray(valid, dtype=np.bool_),
        float(tolerance),
        occluded,
        np.empty(width + kernels.SPARE_SLOTS + 1, dtype=np.float32),
        np.empty(width, dtype=np.uint32),
        np.empty(width, dtype=np.uint32),
    )
    return occluded, "left GT z-buffer"


def discontinuities(
    gt: np.ndarray, valid: np.ndarray, gap: float = 2.0, width: int = 9
) -> np.ndarray:
    """Points within a ``width``-square of a GT jump larger than ``gap`` between 4-neighbours.

    Only jumps between two valid points count, so the border of unknown GT is no boundary.
    """
    return _dilated(_jumps(gt, valid, gap)[0], width)


def _jumps(gt: np.ndarray, valid: np.ndarray, gap: float) -> tuple[np.ndarray, int]:
    """Both ends of every 4-neighbour jump, and the number of connected points (one pass)."""
    jumps = np.empty(gt.shape, dtype=np.bool_)
    connected = kernels.jump_marks(
        np.ascontiguousarray(gt, dtype=np.float32),
        np.ascontiguousarray(valid, dtype=np.bool_),
        float(gap),
        jumps,
        np.empty((5, gt.shape[1] + 1), dtype=np.bool_),
    )
    return jumps, int(connected)


def _dilated(jumps: np.ndarray, width: int) -> np.ndarray:
    """``jumps`` dilated by a ``width``-square (OpenCV on the same bytes viewed as 0/1)."""
    if width <= 1:
        return jumps
    return cv2.dilate(jumps.view(np.uint8), np.ones((width, width), np.uint8)).view(np.bool_)


BOUNDARY_MODES = ("auto", "dense", "sparse")
#: Under ``auto``, GT is sparse when fewer than this share of its valid points have a valid
#: neighbour both vertically and horizontally (dense GT: > 80 %; semi-dense KITTI: > 20 %;
#: a LiDAR scan, whose beams are rows several pixels apart: ~0 %).
SPARSE_CONNECTED_SHARE = 0.02
#: Fewer valid points than this are too few to tell a scan from a small dense map: dense.
SPARSE_MIN_POINTS = 256


def is_sparse(valid: np.ndarray) -> bool:
    """Whether GT is sparse: almost no valid point has valid vertical and horizontal neighbours.

    Maps one pixel high or wide, or with fewer than :data:`SPARSE_MIN_POINTS` valid points,
    are never sparse (the 4-neighbour rule is then kept).
    """
    if not _may_be_sparse(valid):
        return False
    vertical = np.zeros(valid.shape, bool)
    vertical[1:] |= valid[:-1]
    vertical[:-1] |= valid[1:]
    horizontal = np.zeros(valid.shape, bool)
    horizontal[:, 1:] |= valid[:, :-1]
    horizontal[:, :-1] |= valid[:, 1:]
    return _sparse_share(valid, int((valid & vertical & horizontal).sum()))


def _may_be_sparse(valid: np.ndarray, count: int | None = None) -> bool:
    count = int(np.count_nonzero(valid)) if count is None else count
    return min(valid.shape) >= 2 and count >= SPARSE_MIN_POINTS


def _sparse_share(valid: np.ndarray, connected: int) -> bool:
    """The rule of :func:`is_sparse` given the number of connected valid points."""
    count = int(np.count_nonzero(valid))
    return _may_be_sparse(valid, count) and connected < SPARSE_CONNECTED_SHARE * count


def sparse_discontinuities(
    gt: np.ndarray, valid: np.ndarray, gap: float = 2.0, width: int = 9
) -> np.ndarray:
    """Valid points with a valid point in their ``width``-square differing by more than ``gap``.

    The boundary of sparse GT (LiDAR): 4-neighbour jumps need neighbours a scan rarely has.
    The square is centred on the point (``width // 2`` each side). Such a neighbour exists
    exactly when the square's largest valid value exceeds ``d`` by more than ``gap`` or its
    smallest falls short by more (float32 differences are monotonic): a max and a min filter.
    """
    gt32 = np.ascontiguousarray(gt, dtype=np.float32)
    side = 2 * (max(width, 1) // 2) + 1
    square = np.ones((side, side), np.uint8)
    highest = cv2.dilate(np.where(valid, gt32, np.float32(-np.inf)), square)
    lowest = cv2.erode(np.where(valid, gt32, np.float32(np.inf)), square)
    with np.errstate(invalid="ignore"):
        return valid & ((highest - gt32 > gap) | (gt32 - lowest > gap))


def visibility_set(
    gt: np.ndarray,
    valid: np.ndarray,
    *,
    nonocc: np.ndarray | None = None,
    disc: np.ndarray | None = None,
    gt_right: np.ndarray | None = None,
    gap: float = 2.0,
    width: int = 9,
    tolerance: float = 1.0,
    boundary_mode: str = "auto",
) -> CriterionSet:
    """``occluded`` / ``boundary`` / ``interior`` (with official masks: all∖nonocc, disc, nonocc∖disc).

    ``boundary_mode``: ``dense`` (4-neighbour jumps dilated by ``width``), ``sparse``
    (:func:`sparse_discontinuities`) or ``auto`` (sparse when :func:`is_sparse`).
    """
    options = VisibilityOptions(nonocc, disc, gt_right, gap, width, tolerance, boundary_mode)
    occluded, near_jump, source = _visibility_masks(gt, valid, options)
    labels = np.empty(gt.shape, np.int32)
    kernels.visibility_labels(
        _flat(occluded, np.bool_), _flat(near_jump, np.bool_), labels.reshape(-1)
    )
    return _partitioning("visibility", labels, VISIBILITY, source)


@dataclass(frozen=True)
class VisibilityOptions:
    """How the ``visibility`` classes are found (see :func:`visibility_set`)."""

    nonocc: np.ndarray | None = None
    disc: np.ndarray | None = None
    gt_right: np.ndarray | None = None
    gap: float = 2.0
    width: int = 9
    tolerance: float = 1.0
    boundary_mode: str = "auto"


def _visibility_masks(
    gt: np.ndarray, valid: np.ndarray, options: VisibilityOptions
) -> tuple[np.ndarray, np.ndarray, str]:
    """Occluded points, points near a discontinuity and where both came from."""
    nonocc, disc, gap, width = options.nonocc, options.disc, options.gap, options.width
    occluded, source = occlusion(
        gt, valid, nonocc=nonocc, gt_right=options.gt_right, tolerance=options.tolerance
    )
    if disc is not None:
        _check_shape("the 'disc' mask", disc, gt)
        return occluded, inside_mask("the 'disc' mask", disc), source + ", official disc mask"
    sparse_boundary = source + ", sparse-GT boundary"
    if options.boundary_mode == "sparse":
        return occluded, sparse_discontinuities(gt, valid, gap, width), sparse_boundary
    jumps, connected = _jumps(gt, valid, gap)  # the sparse test comes from the same pass
    if options.boundary_mode == "auto" and _sparse_share(valid, connected):
        return occluded, sparse_discontinuities(gt, valid, gap, width), sparse_boundary
    return occluded, _dilated(jumps, width), source


def legacy_set(visibility: CriterionSet) -> CriterionSet:
    """The overlapping Middlebury criteria ``nonocc`` ⊂ ``all`` ⊃ ``disc`` (for comparison only).

    Built on the visibility classes: occluded, boundary (= disc), interior.
    """
    return CriterionSet(
        "legacy",
        visibility.labels,
        LEGACY,
        _LEGACY_MEMBERSHIP,
        overlapping=True,
        source=visibility.source,
    )


# classes: 0 occluded, 1 boundary (disc), 2 interior: nonocc = {1, 2}, all = all, disc = {1}
_LEGACY_MEMBERSHIP = np.array([[False, True, True], [True, True, True], [False, True, False]])
