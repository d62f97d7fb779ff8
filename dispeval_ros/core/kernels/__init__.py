"""Compiled per-pixel loops: the only place where the engine touches every pixel.

Everything here is numba-compiled (cached on disk, set up once in ``_jit``) and works on plain
arrays, one module per family: ``estimates`` (coding, missing-estimate policy), ``sums``
(accumulation), ``temporal`` (the pair measures' accumulation), ``partition``, ``labels``
(occlusion, visibility, jumps), ``clustering`` (k-means classes); ``layout`` is the
accumulator's column layout. The scoring
path is two passes per method: :func:`normalise_estimate` (validity + the missing-estimate
policy, row by row) and :func:`accumulate_cells` (one fused pass over the valid-GT pixels in
partition order, summing every measure's terms per cell). GT-side terms are prepared once
per ground-truth map by the partition.
"""

from __future__ import annotations

from dispeval_ros.core.kernels._jit import _FAST as _FAST  # gtfree.py compiles with the same flags
from dispeval_ros.core.kernels.clustering import (
    KMEANS_BLOCK,
    kmeans_three,
)
from dispeval_ros.core.kernels.estimates import (
    POLICY_IGNORE,
    POLICY_INTERPOLATE,
    POLICY_THESIS,
    POSITIVE,
    coding,
    gather_estimate,
    normalise_estimate,
)
from dispeval_ros.core.kernels.labels import (
    SPARE_SLOTS,
    forward_warp_occlusion,
    jump_marks,
    left_right_occlusion,
    threshold_labels,
    visibility_labels,
)
from dispeval_ros.core.kernels.layout import (
    FIELD_BAD,
    FIELD_BMPRE,
    FIELD_COUNT,
    FIELD_D1,
    FIELD_EVAL,
    FIELD_LRC,
    FIELD_N,
    FIELD_N_LRC,
    FIELD_N_VPE,
    FIELD_SUM_E,
    FIELD_SUM_E2,
    FIELD_SUM_EZ,
    FIELD_SUM_EZ2,
    FIELD_SUM_IZ2,
    FIELD_SUM_REL,
    FIELD_SUM_RELZ,
    FIELD_SUM_VPE,
    FIELD_SZE,
    FIELD_VALID,
    MAX_THRESHOLDS,
)
from dispeval_ros.core.kernels.partition import (
    RUN_PIXELS,
    pack_valid,
    partition_cells,
    valid_points,
    valid_range,
)
from dispeval_ros.core.kernels.sums import (
    accumulate_cells,
)

__all__ = [
    "FIELD_BAD",
    "FIELD_BMPRE",
    "FIELD_COUNT",
    "FIELD_D1",
    "FIELD_EVAL",
    "FIELD_LRC",
    "FIELD_N",
    "FIELD_N_LRC",
    "FIELD_N_VPE",
    "FIELD_SUM_E",
    "FIELD_SUM_E2",
    "FIELD_SUM_EZ",
    "FIELD_SUM_EZ2",
    "FIELD_SUM_IZ2",
    "FIELD_SUM_REL",
    "FIELD_SUM_RELZ",
    "FIELD_SUM_VPE",
    "FIELD_SZE",
    "FIELD_VALID",
    "KMEANS_BLOCK",
    "MAX_THRESHOLDS",
    "POLICY_IGNORE",
    "POLICY_INTERPOLATE",
    "POLICY_THESIS",
    "POSITIVE",
    "RUN_PIXELS",
    "SPARE_SLOTS",
    "accumulate_cells",
    "coding",
    "forward_warp_occlusion",
    "gather_estimate",
    "jump_marks",
    "kmeans_three",
    "left_right_occlusion",
    "normalise_estimate",
    "pack_valid",
    "partition_cells",
    "threshold_labels",
    "valid_points",
    "valid_range",
    "visibility_labels",
]
