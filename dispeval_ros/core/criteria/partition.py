"""Criterion sets combined into one :class:`Partition` of cells, built by one kernel pass.

:func:`build_partition` combines label images; :func:`standard_partition` lets the kernel
compute the visibility and 3-means classes itself while it builds the cells (no label images).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from dispeval_ros.core import kernels
from dispeval_ros.core.camera import Camera
from dispeval_ros.core.criteria.base import (
    CRITERION_SETS,
    DEPTH,
    LEGACY,
    VISIBILITY,
    CriterionSet,
    _flat,
)
from dispeval_ros.core.criteria.depth import _thresholds_text, depth_set, kmeans_thresholds
from dispeval_ros.core.criteria.visibility import (
    _LEGACY_MEMBERSHIP,
    VisibilityOptions,
    _visibility_masks,
)
from dispeval_ros.errors import ConfigurationError


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
