"""Evaluation criteria as a set partition of the valid ground-truth points (METHOD.md §2).

A *criterion set* (``all``, ``visibility``, ``depth``, ``roi``, ``legacy``) gives every valid
point one class. Several sets are combined into one :class:`Partition`: a single label
image of *cells* (one cell per combination of classes) plus a membership matrix saying
which cells make up each criterion. Scoring then accumulates per cell in one pass, and every
criterion's sums are sums over its cells: no per-criterion masks or copies, and the
overlapping legacy Middlebury criteria fit the same scheme.

One module per concern: :mod:`.base` (the set record, valid points), :mod:`.visibility`
(occlusion and boundary masks, ``legacy``), :mod:`.depth` (3-means thresholds, ranges),
:mod:`.regions` (ROI labels, texture) and :mod:`.partition` (cells);
:mod:`.empty` says why a criterion can hold no point.
"""

from dispeval_ros.core.criteria.base import (
    CRITERION_SETS,
    DEPTH,
    LEGACY,
    NOT_EVALUATED,
    VISIBILITY,
    CriterionSet,
    all_set,
    size_text,
    valid_ground_truth,
)
from dispeval_ros.core.criteria.depth import (
    LIDAR_DEPTH_RANGES,
    SPARSE_KMEANS_SHARE,
    depth_set,
    kmeans_thresholds,
)
from dispeval_ros.core.criteria.empty import EMPTY_REASONS, empty_reason
from dispeval_ros.core.criteria.partition import (
    STANDARD_SETS,
    Partition,
    build_partition,
    standard_partition,
)
from dispeval_ros.core.criteria.regions import (
    TEXTURE,
    TEXTURE_THRESHOLD,
    TEXTURE_WINDOW,
    roi_set,
    texture_set,
)
from dispeval_ros.core.criteria.visibility import (
    BOUNDARY_MODES,
    SPARSE_CONNECTED_SHARE,
    SPARSE_MIN_POINTS,
    VisibilityOptions,
    discontinuities,
    is_sparse,
    legacy_set,
    occlusion,
    sparse_discontinuities,
    visibility_set,
)
from dispeval_ros.core.masks import inside_mask

__all__ = [
    "BOUNDARY_MODES",
    "CRITERION_SETS",
    "DEPTH",
    "EMPTY_REASONS",
    "LEGACY",
    "LIDAR_DEPTH_RANGES",
    "NOT_EVALUATED",
    "SPARSE_CONNECTED_SHARE",
    "SPARSE_KMEANS_SHARE",
    "SPARSE_MIN_POINTS",
    "STANDARD_SETS",
    "TEXTURE",
    "TEXTURE_THRESHOLD",
    "TEXTURE_WINDOW",
    "VISIBILITY",
    "CriterionSet",
    "Partition",
    "VisibilityOptions",
    "all_set",
    "build_partition",
    "depth_set",
    "discontinuities",
    "empty_reason",
    "inside_mask",
    "is_sparse",
    "kmeans_thresholds",
    "legacy_set",
    "occlusion",
    "roi_set",
    "size_text",
    "sparse_discontinuities",
    "standard_partition",
    "texture_set",
    "valid_ground_truth",
    "visibility_set",
]
