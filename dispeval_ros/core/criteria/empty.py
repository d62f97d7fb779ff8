"""Why a criterion can hold no point: one sentence per class, read by every front end.

A criterion without points has no defined score (ratios are undefined, sums are 0 for every
method), so it is never an objective of the models (:mod:`dispeval_ros.core.objectives`);
the tables print this text instead of leaving a row of dashes unexplained.
"""

from __future__ import annotations

import re

from dispeval_ros.core.criteria.regions import TEXTURE_THRESHOLD, TEXTURE_WINDOW
from dispeval_ros.core.criteria.visibility import VisibilityOptions

_GAP = f"{VisibilityOptions.gap:g} px"
_TEXTURE = (
    f"mean squared horizontal gradient over {TEXTURE_WINDOW}×{TEXTURE_WINDOW} "
    f"below {TEXTURE_THRESHOLD:g} grey levels²"
)
EMPTY_REASONS: dict[str, str] = {
    "all": "the ground truth has no valid point (finite and > 0)",
    "occluded": "no valid GT point is occluded in the right view",
    "boundary": (
        f"the GT has no disparity jump > {_GAP} between valid 4-neighbours (semi-dense GT, "
        "as KITTI's or ETH3D's, leaves out the points at depth edges)"
    ),
    "interior": "every valid GT point is occluded or near a disparity jump",
    "nonocc": "every valid GT point is occluded",
    "disc": f"the GT has no disparity jump > {_GAP} between valid neighbours",
    "near": "3-means of the GT disparities left this cluster empty (too few distinct depths)",
    "mid": "3-means of the GT disparities left this cluster empty (too few distinct depths)",
    "far": "3-means of the GT disparities left this cluster empty (too few distinct depths)",
    "roi": "the region-of-interest mask covers no valid point",
    "elsewhere": "the region-of-interest mask covers every valid point",
    "unlabelled": "every valid point has a named label",
    "textured": f"no point is textured ({_TEXTURE} everywhere)",
    "textureless": f"no point is textureless ({_TEXTURE})",
}
"""The classes of the criterion sets (``core.criteria``), by criterion name."""
_RANGE = re.compile(r"^\d[\d.e+-]*(-\d[\d.e+-]*|\+)\D*$")


def empty_reason(criterion: str) -> str:
    """Why ``criterion`` (``gtfree:`` criteria too) can have no point, in one sentence."""
    name = criterion.rpartition(":")[2]
    if name in EMPTY_REASONS:
        return EMPTY_REASONS[name]
    if _RANGE.match(name):
        return "no valid GT point lies in this depth range"
    return "no valid point carries this label"
