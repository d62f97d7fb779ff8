"""What every criterion set is made of: the record, the valid GT points, shape checks.

Kept apart from the set builders so each of them (visibility, depth, regions) and the
partition read one definition of a set and of a valid point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dispeval_ros.core import kernels
from dispeval_ros.core.masks import inside_mask
from dispeval_ros.errors import ShapeMismatchError

CRITERION_SETS = ("all", "visibility", "depth", "roi", "legacy")
VISIBILITY = ("occluded", "boundary", "interior")
DEPTH = ("near", "mid", "far")
LEGACY = ("nonocc", "all", "disc")
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
        valid &= inside_mask("the 'all' mask", all_mask)
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
