"""Evaluation criteria as a set partition of the valid ground-truth points (METHOD.md §2).

A *criterion set* (``all``, ``visibility``, ``depth``, ``roi``, ``legacy``) gives every valid
point one class. Several sets are combined into one :class:`Partition`: a single label
image of *cells* (one cell per combination of classes) plus a membership matrix saying
which cells make up each criterion. Scoring then accumulates per cell in one pass, and every
criterion's sums are sums over its cells: no per-criterion masks or copies, and the
overlapping legacy Middlebury criteria fit the same scheme.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from dispeval_ros.core import kernels
from dispeval_ros.core.camera import Camera
from dispeval_ros.errors import ConfigurationError, EmptyGroundTruthError, ShapeMismatchError

CRITERION_SETS = ("all", "visibility", "depth", "roi", "legacy")
VISIBILITY = ("occluded", "boundary", "interior")
DEPTH = ("near", "mid", "far")
LEGACY = ("nonocc", "all", "disc")
#: Depth ranges (metres) of the ``depth`` criteria for LiDAR GT: 3-means of a scan's
#: disparities would split mostly by distance along the ground, ranges say what users mean.
LIDAR_DEPTH_RANGES = ((0.0, 10.0), (10.0, 30.0), (30.0, float("inf")))
NOT_EVALUATED = -1


@dataclass(frozen=True)
class CriterionSet:
    """One family of criteria: a class index per valid pixel and the criteria it forms.

    ``membership[i, c]`` says whether class ``c`` belongs to criterion ``criteria[i]``; for
    a partitioning set it is the identity, for the legacy Middlebury set it overlaps.
    """

    name: str
    labels: np.ndarray
    criteria: tuple[str, ...]
    membership: np.ndarray
    overlapping: bool = False
    source: str = ""

    @property
    def classes(self) -> int:
        """Number of classes (columns of ``membership``)."""
        return int(self.membership.shape[1])


def _partitioning(
    name: str, labels: np.ndarray, criteria: tuple[str, ...], source: str = ""
) -> CriterionSet:
    return CriterionSet(
        name,
        labels.astype(np.int32, copy=False),
        criteria,
        np.eye(len(criteria), dtype=bool),
        source=source,
    )


def valid_ground_truth(gt: np.ndarray, all_mask: np.ndarray | None = None) -> np.ndarray:
    """Valid GT points: finite and > 0, restricted to an official ``all`` mask if given."""
    if gt.dtype == np.float32 and gt.flags.c_contiguous:  # as the evaluator holds GT: one pass
        valid = np.empty(gt.shape, dtype=np.bool_)
        kernels.valid_points(gt.reshape(-1), valid.reshape(-1))
    else:
        valid = np.isfinite(gt) & (gt > 0)
    if all_mask is not None:
        _check_shape("the 'all' mask", all_mask, gt)
        valid &= all_mask.astype(bool, copy=False)
    return valid


def _check_shape(what: str, array: np.ndarray, gt: np.ndarray) -> None:
    if array.shape != gt.shape:
        raise ShapeMismatchError(
            f"{what} is {size_text(array.shape)} but the ground truth is {size_text(gt.shape)}"
        )


def size_text(shape: tuple[int, ...]) -> str:
    """An image size as users read it everywhere: width × height (× channels)."""
    if len(shape) < 2:
        return "×".join(str(n) for n in shape)
    return "×".join(str(n) for n in (shape[1], shape[0], *shape[2:]))


def _flat(array: np.ndarray, dtype: type | None = None) -> np.ndarray:
    """A contiguous 1-D view (a copy only if needed): kernels loop over flat arrays."""
    return np.ascontiguousarray(array, dtype=dtype).reshape(-1)


def all_set(valid: np.ndarray) -> CriterionSet:
    """The single criterion ``all``: every valid point."""
    return _partitioning("all", np.zeros(valid.shape, np.int32), ("all",), "valid GT")


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
        return valid & ~nonocc.astype(bool, copy=False), "official mask"
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
        return occluded, disc.astype(bool, copy=False), source + ", official disc mask"
    sparse_boundary = source + ", sparse-GT boundary"
    if options.boundary_mode == "sparse":
        return occluded, sparse_discontinuities(gt, valid, gap, width), sparse_boundary
    jumps, connected = _jumps(gt, valid, gap)  # the sparse test comes from the same pass
    if options.boundary_mode == "auto" and _sparse_share(valid, connected):
        return occluded, sparse_discontinuities(gt, valid, gap, width), sparse_boundary
    return occluded, _dilated(jumps, width), source


def kmeans_thresholds(
    gt: np.ndarray, valid: np.ndarray, max_iterations: int = 100
) -> tuple[float, float]:
    """Deterministic 1-D 3-means of the valid GT disparities: the two decision thresholds.

    Lloyd's algorithm can stop in a poor local optimum (on Middlebury tsukuba, twice the
    optimal within-cluster error from range-based starting points), so it starts from the
    global optimum over a fine histogram (every pair of cuts at bin edges, exact bin
    moments) and then iterates on the exact values until the centroids no longer change.
    Each step sums whole bins from their moments and splits value by value only the bins a
    threshold falls in. A value equal to a threshold goes to the lower (farther) cluster.
    ``valid`` marks finite values > 0 only (:func:`valid_ground_truth`, maybe narrowed).
    """
    flat_valid = _flat(valid, np.bool_)
    count = int(np.count_nonzero(flat_valid))
    if not count:
        raise EmptyGroundTruthError("the ground truth has no valid point (all NaN, inf or ≤ 0)")
    values = _flat(gt)
    if values.dtype not in (np.float32, np.float64):
        values = values.astype(np.float64)
    if count < SPARSE_KMEANS_SHARE * flat_valid.shape[0]:  # mostly invalid: read only the valid
        packed = np.empty(count + 1, dtype=values.dtype)  # + 1: the kernel writes one past
        kernels.pack_valid(values, flat_valid, packed)
        values, flat_valid = packed[:count], np.ones(count, dtype=np.bool_)
    bits = values.view(np.int32 if values.dtype == np.float32 else np.int64)
    limits = np.array([np.iinfo(bits.dtype).max, -1], dtype=bits.dtype)
    kernels.valid_range(bits, flat_valid, limits)
    lo, hi = (float(value) for value in limits.view(values.dtype))
    thresholds = np.empty(2)
    kernels.kmeans_three(
        values,
        flat_valid,
        lo,
        hi,
        max_iterations,
        np.zeros(_KMEANS_BINS + 1, dtype=np.int64),
        np.zeros((8, _KMEANS_BINS + 1)),
        np.empty(values.shape[0]),  # untouched pages cost nothing: only a few bins are copied
        np.empty(values.shape[0], dtype=np.uint16),
        thresholds,
    )
    return float(thresholds[0]), float(thresholds[1])


_KMEANS_BINS = 512
#: Below this share of valid points, 3-means packs the valid values first (sparse GT).
SPARSE_KMEANS_SHARE = 0.5


def depth_set(
    gt: np.ndarray,
    valid: np.ndarray,
    *,
    camera: Camera | None = None,
    ranges: Sequence[tuple[float, float]] | None = None,
    names: Sequence[str] | None = None,
) -> CriterionSet:
    """``near`` / ``mid`` / ``far`` by 3-means of the disparities, or by metric depth ranges.

    Ranges are ``(from, to)`` in the camera's unit, contiguous, from 0 to ``inf``; points
    with ``d + doffs <= 0`` (infinitely far) fall in the last range.
    """
    if ranges is None:
        low, high = kmeans_thresholds(gt, valid)
        labels = np.empty(gt.shape, np.int32)
        kernels.threshold_labels(_flat(gt), low, high, labels.reshape(-1))
        return _partitioning("depth", labels, DEPTH, _thresholds_text(low, high))
    if camera is None:
        raise ConfigurationError("metric depth ranges need a camera (focal length and baseline)")
    edges = _range_edges(ranges)
    criteria = tuple(names) if names else tuple(_range_name(a, b, camera.unit) for a, b in ranges)
    if len(criteria) != len(ranges):
        raise ConfigurationError(f"{len(ranges)} depth ranges but {len(criteria)} names")
    denominator = np.where(valid, gt, 0.0).astype(np.float64) + camera.doffs
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.where(denominator > 0, camera.fb / denominator, np.inf)
    labels = np.searchsorted(edges, depth, side="right").astype(np.int32) - 1
    labels = np.clip(labels, 0, len(criteria) - 1)
    return _partitioning("depth", labels, criteria, "metric depth ranges")


def _thresholds_text(low: float, high: float) -> str:
    return f"3-means thresholds {low:.6g}, {high:.6g} px"


def _range_edges(ranges: Sequence[tuple[float, float]]) -> np.ndarray:
    if not ranges:
        raise ConfigurationError("depth ranges are empty; give e.g. 0-10,10-30,30-inf")
    starts = [float(a) for a, _ in ranges]
    stops = [float(b) for _, b in ranges]
    if (
        starts[0] != 0.0
        or stops[-1] != np.inf
        or any(a != b for a, b in zip(stops[:-1], starts[1:], strict=True))
        or any(a >= b for a, b in zip(starts, stops, strict=True))
    ):
        shown = ", ".join(f"{a:g}-{b:g}" for a, b in ranges)
        raise ConfigurationError(
            f"depth ranges must be contiguous and increasing from 0 to inf, got {shown}"
        )
    return np.array(starts, dtype=np.float64)


def _range_name(start: float, stop: float, unit: str) -> str:
    return f"{start:g}+{unit}" if stop == np.inf else f"{start:g}-{stop:g}{unit}"


def roi_set(
    valid: np.ndarray,
    roi: np.ndarray,
    names: Mapping[int, str] | None = None,
) -> CriterionSet:
    """``roi`` / ``elsewhere`` from a mask, or named classes of a label image.

    With ``names`` (label value → class name) every listed value is a criterion and all
    other values form ``unlabelled``.
    """
    if roi.shape != valid.shape:
        raise ShapeMismatchError(
            f"the region-of-interest image is {size_text(roi.shape)} but the ground truth is "
            f"{size_text(valid.shape)}"
        )
    if not names:
        labels = np.where(roi.astype(bool, copy=False), 0, 1).astype(np.int32)
        return _partitioning("roi", labels, ("roi", "elsewhere"), "mask")
    values = sorted(names)
    criteria = (*(names[v] for v in values), "unlabelled")
    if len(set(criteria)) != len(criteria):
        raise ConfigurationError(f"label names must be unique, got {', '.join(criteria)}")
    lookup = np.full(int(max(int(roi.max()), *values)) + 1, len(values), np.int32)
    lookup[np.asarray(values, dtype=np.int64)] = np.arange(len(values), dtype=np.int32)
    labels = lookup[np.clip(roi.astype(np.int64), 0, None)]
    return _partitioning("roi", labels, criteria, "label image")


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


def _legacy_layout(visibility: CriterionSet) -> CriterionSet:
    return _layout("legacy", LEGACY, _LEGACY_MEMBERSHIP, overlapping=True, source=visibility.source)


@dataclass(frozen=True)
class Partition:
    """Criteria of one GT map as cells: built once, used for every method scored on that GT.

    ``cells`` labels every pixel with its cell (``-1``: not evaluated); ``order`` lists the
    evaluated pixel indices grouped by cell, ``offsets[c]:offsets[c+1]`` being cell ``c``;
    ``membership[i, c]`` says whether cell ``c`` is part of criterion ``criteria[i]``.
    """

    cells: np.ndarray
    criteria: tuple[str, ...]
    membership: np.ndarray
    order: np.ndarray
    offsets: np.ndarray
    overlapping: tuple[str, ...]
    sources: Mapping[str, str]

    @property
    def shape(self) -> tuple[int, int]:
        """Image size (rows, columns)."""
        return (int(self.cells.shape[0]), int(self.cells.shape[1]))

    def counts(self) -> dict[str, int]:
        """Number of points per criterion."""
        per_cell = np.diff(self.offsets).astype(np.int64)
        return {
            name: int(per_cell[self.membership[i]].sum()) for i, name in enumerate(self.criteria)
        }

    def mask(self, criterion: str) -> np.ndarray:
        """Boolean image of one criterion (for display and tests, not for scoring)."""
        index = self.criteria.index(criterion)
        cells_in = np.flatnonzero(self.membership[index])
        return np.isin(self.cells, cells_in)


_NO_LABELS = np.empty((0, 0), np.int32)


def _layout(
    name: str,
    criteria: tuple[str, ...],
    membership: np.ndarray,
    *,
    overlapping: bool = False,
    source: str = "",
) -> CriterionSet:
    """A criterion set without its label image, for :func:`standard_partition` only.

    The partition kernel computes the classes of such a set itself.
    """
    return CriterionSet(name, _NO_LABELS, criteria, membership, overlapping, source)


def build_partition(valid: np.ndarray, sets: Sequence[CriterionSet]) -> Partition:
    """Combine criterion sets into cells (the product of their classes) over the valid points."""
    if not sets:
        raise ConfigurationError("no criterion set given; choose from " + ", ".join(CRITERION_SETS))
    folded: np.ndarray | None = None  # the labels of every set with classes, as one image
    stride = 1
    for criterion_set in sets:
        if criterion_set.classes > 1:
            labels = _flat(criterion_set.labels, np.int32)
            term = labels if stride == 1 else labels * stride
            folded = term if folded is None else folded + term  # new arrays: labels stay as given
        stride *= criterion_set.classes
    flat_valid = _flat(valid, np.bool_)
    cells = np.empty(valid.shape, np.int32)
    unused = cells.reshape(-1).view(np.float32)  # stands in for the inputs with stride 0
    return _partition(
        valid,
        sets,
        cells,
        (flat_valid, flat_valid, 0),
        (unused, 0.0, 0.0, 0),
        (cells.reshape(-1), 0) if folded is None else (folded.astype(np.int32, copy=False), 1),
        None,
    )[0]


def standard_partition(
    gt: np.ndarray,
    valid: np.ndarray,
    names: Sequence[str],
    options: VisibilityOptions | None = None,
    *,
    camera: Camera | None = None,
    depth_ranges: Sequence[tuple[float, float]] | None = None,
) -> tuple[Partition, np.ndarray]:
    """The partition of standard criterion sets and the GT in partition order (float32).

    Sets ``all``, ``visibility``, ``legacy`` and ``depth`` (3-means, or ``depth_ranges`` with
    a ``camera``) in the order of ``names``: the partition :func:`build_partition` makes of
    :func:`all_set`, :func:`visibility_set`, :func:`legacy_set` and :func:`depth_set`, but the
    kernel computes the visibility and 3-means classes per pixel while it builds the cells
    (no label images).
    """
    unknown = set(names) - set(STANDARD_SETS)
    if unknown or not names:
        raise ConfigurationError(f"no standard criterion sets: {', '.join(names)}")
    gt32 = np.ascontiguousarray(gt, dtype=np.float32)
    cells = np.empty(gt.shape, np.int32)
    occluded = near_jump = valid
    visibility: CriterionSet | None = None
    low = high = 0.0
    visibility_stride = depth_stride = 0
    labels = (cells.reshape(-1), 0)  # a label image and its stride: depth by ranges
    layouts: list[CriterionSet] = []
    stride = 1
    for name in names:
        if name == "all":
            layouts.append(_layout("all", ("all",), np.eye(1, dtype=bool), source="valid GT"))
        elif name == "depth" and depth_ranges:
            layouts.append(depth_set(gt32, valid, camera=camera, ranges=depth_ranges))
            labels = (_flat(layouts[-1].labels, np.int32), stride)
        elif name == "depth":
            low, high = kmeans_thresholds(gt32, valid)
            depth = _layout(
                "depth", DEPTH, np.eye(3, dtype=bool), source=_thresholds_text(low, high)
            )
            layouts.append(depth)
            depth_stride = stride
        else:
            if visibility is None:
                occluded, near_jump, source = _visibility_masks(
                    gt32, valid, options or VisibilityOptions()
                )
                visibility = _layout("visibility", VISIBILITY, np.eye(3, dtype=bool), source=source)
            layouts.append(visibility if name == "visibility" else _legacy_layout(visibility))
            visibility_stride += stride
        stride *= layouts[-1].classes
    return _partition(
        valid,
        layouts,
        cells,
        (_flat(occluded, np.bool_), _flat(near_jump, np.bool_), visibility_stride),
        (gt32.reshape(-1), low, high, depth_stride),
        labels,
        gt32.reshape(-1),
    )


STANDARD_SETS = ("all", "visibility", "legacy", "depth")
"""The sets :func:`standard_partition` builds (``depth``: by 3-means)."""


def _partition(
    valid: np.ndarray,
    sets: Sequence[CriterionSet],
    cells: np.ndarray,
    visibility: tuple[np.ndarray, np.ndarray, int],
    depth: tuple[np.ndarray, float, float, int],
    labels: tuple[np.ndarray, int],
    values: np.ndarray | None,
) -> tuple[Partition, np.ndarray]:
    """Cells, order and the values in partition order (empty without ``values``) from one kernel.

    ``visibility``: occluded, near-jump masks and stride; ``depth``: values, thresholds and
    stride; ``labels``: a label image and its stride (strides 0: unused).
    """
    n_cells = 1
    for criterion_set in sets:
        n_cells *= criterion_set.classes
    criteria: list[str] = []
    rows: list[np.ndarray] = []
    overlapping: list[str] = []
    sources: dict[str, str] = {}
    cell_ids = np.arange(n_cells)
    stride = 1
    for criterion_set in sets:
        classes = (cell_ids // stride) % criterion_set.classes
        stride *= criterion_set.classes
        sources[criterion_set.name] = criterion_set.source
        for i, name in enumerate(criterion_set.criteria):
            row = criterion_set.membership[i][classes]
            if name in criteria:
                if not np.array_equal(rows[criteria.index(name)], row):
                    raise ConfigurationError(f"two criterion sets define '{name}' differently")
                continue
            criteria.append(name)
            rows.append(row)
            if criterion_set.overlapping:
                overlapping.append(name)
    flat_valid = _flat(valid, np.bool_)
    offsets = np.empty(n_cells + 1, dtype=np.int64)
    evaluated = int(np.count_nonzero(flat_valid))
    order = np.empty(evaluated, dtype=np.int32)
    sorted_values = np.empty(0 if values is None else evaluated, dtype=np.float32)
    occluded, near_jump, visibility_stride = visibility
    depth_values, low, high, depth_stride = depth
    label_image, labels_stride = labels
    kernels.partition_cells(
        flat_valid,
        occluded,
        near_jump,
        visibility_stride,
        depth_values,
        low,
        high,
        depth_stride,
        label_image,
        labels_stride,
        cells.reshape(-1),
        np.zeros((4, n_cells + 1), dtype=np.int64),
        offsets,
        order,
        sorted_values,
    )
    order = order[: offsets[-1]]  # all of it unless a set labelled a valid point negative
    partition = Partition(
        cells=cells,
        criteria=tuple(criteria),
        membership=np.array(rows, dtype=bool),
        order=order,
        offsets=offsets,
        overlapping=tuple(overlapping),
        sources=sources,
    )
    return partition, sorted_values[: order.shape[0]]


TEXTURE = ("textured", "textureless")
#: Middlebury 2001 taxonomy (Scharstein & Szeliski, MSR-TR-2001-81, §5.1): a pixel is
#: textureless where the squared horizontal intensity gradient, averaged over a square window
#: of this width, is below :data:`TEXTURE_THRESHOLD` (grey levels², 8-bit intensities).
TEXTURE_WINDOW = 3
TEXTURE_THRESHOLD = 4.0


def texture_set(
    image: np.ndarray,
    window: int = TEXTURE_WINDOW,
    threshold: float = TEXTURE_THRESHOLD,
) -> CriterionSet:
    """``textured`` / ``textureless`` from the left image alone (never from a method's output).

    The horizontal gradient is the forward difference ``I(x+1, y) − I(x, y)`` (0 in the last
    column); its square is box-averaged over ``window × window`` pixels (borders reflected).
    """
    if image.ndim != 2:
        raise ConfigurationError(f"the texture criteria need a grey image, got shape {image.shape}")
    if window < 1:
        raise ConfigurationError(f"the texture window must be at least 1 pixel, got {window}")
    grey = image.astype(np.float32)
    squared = np.zeros(grey.shape, np.float32)
    squared[:, :-1] = np.square(grey[:, 1:] - grey[:, :-1])
    mean = cv2.boxFilter(squared, -1, (window, window), borderType=cv2.BORDER_REFLECT_101)
    labels = (mean < threshold).astype(np.int32)
    return _partitioning(
        "texture",
        labels,
        TEXTURE,
        f"mean squared horizontal gradient over {window}×{window} < {threshold:g} grey levels²",
    )
