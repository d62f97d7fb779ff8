"""Official benchmark protocols: MiddEval3, KITTI 2015, KITTI 2012 and ETH3D, exactly.

Each protocol is a preset of regions, measures, thresholds, invalid-estimate handling and the
official tool's arithmetic, so that a user's numbers can be put beside a leaderboard's. One
module per benchmark (:mod:`.middeval3`, :mod:`.kitti2015`, :mod:`.kitti2012`, :mod:`.eth3d`)
holds its :class:`Protocol` with its own frame and summary functions; :mod:`.common` what they
share, :mod:`.registry` the protocols by name and dispatch, :mod:`.streams` the presets for
recorded streams. Nothing here reads files: the dataset trees are found by
:mod:`dispeval_ros.io.benchmarks`.
"""

from dispeval_ros.core.protocols.common import (
    EXACT,
    F32,
    OFFICIAL,
    RESULT_ENCODINGS,
    Arithmetic,
    FrameData,
    FrameFunction,
    FrameResult,
    Protocol,
    ResultLayout,
    SummaryFunction,
    SummaryTable,
    config_sha256,
    float32_sum,
    float64_sum,
    quantile_index,
)
from dispeval_ros.core.protocols.eth3d import ETH3D, eth3d_frame, eth3d_summary
from dispeval_ros.core.protocols.kitti import kitti_interpolation
from dispeval_ros.core.protocols.kitti2012 import KITTI2012, kitti2012_frame, kitti2012_summary
from dispeval_ros.core.protocols.kitti2015 import (
    KITTI2015,
    kitti2015_frame,
    kitti2015_summary,
    kitti2015_values,
)
from dispeval_ros.core.protocols.middeval3 import (
    MIDDEVAL3,
    MIDDEVAL3_WEIGHTS,
    MIDDEVAL3_WEIGHTS_SOURCE,
    middeval3_frame,
    middeval3_summary,
)
from dispeval_ros.core.protocols.registry import (
    PROTOCOLS,
    evaluate_frame,
    get_protocol,
    moved_digits,
    objective_matrix,
    resolve,
    summarize_frames,
)
from dispeval_ros.core.protocols.streams import STREAM_PRESETS, StreamPreset, stream_preset

__all__ = [
    "ETH3D",
    "EXACT",
    "F32",
    "KITTI2012",
    "KITTI2015",
    "MIDDEVAL3",
    "MIDDEVAL3_WEIGHTS",
    "MIDDEVAL3_WEIGHTS_SOURCE",
    "OFFICIAL",
    "PROTOCOLS",
    "RESULT_ENCODINGS",
    "STREAM_PRESETS",
    "Arithmetic",
    "FrameData",
    "FrameFunction",
    "FrameResult",
    "Protocol",
    "ResultLayout",
    "StreamPreset",
    "SummaryFunction",
    "SummaryTable",
    "config_sha256",
    "eth3d_frame",
    "eth3d_summary",
    "evaluate_frame",
    "float32_sum",
    "float64_sum",
    "get_protocol",
    "kitti2012_frame",
    "kitti2012_summary",
    "kitti2015_frame",
    "kitti2015_summary",
    "kitti2015_values",
    "kitti_interpolation",
    "middeval3_frame",
    "middeval3_summary",
    "moved_digits",
    "objective_matrix",
    "quantile_index",
    "resolve",
    "stream_preset",
    "summarize_frames",
]
