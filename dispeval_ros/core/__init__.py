"""Pure evaluation math: criteria, measures and models. No files, no ROS.

Everything here takes numpy arrays and small records and returns numbers, so every front
end (files, bags, ROS topics, DDS) shares one tested implementation.
"""

from typing import TYPE_CHECKING

from dispeval_ros.lazy import lazy_exports

# numba kernels load when a name is first used, not with ``import dispeval_ros.core.records``
__getattr__, __dir__ = lazy_exports(
    globals(),
    {
        "dispeval_ros.core.camera": ("Camera",),
        "dispeval_ros.core.confidence": (
            "ConfidencePreset",
            "ConfidenceScorer",
            "ConfidenceSums",
            "parse_preset",
        ),
        "dispeval_ros.core.criteria": (
            "CRITERION_SETS",
            "CriterionSet",
            "Partition",
            "VisibilityOptions",
            "build_partition",
            "standard_partition",
        ),
        "dispeval_ros.core.egomotion": (
            "EgoMotionOptions",
            "FlickerWindow",
            "MotionFrame",
            "PinholeCamera",
            "TemporalSums",
            "egomotion_residual",
            "flicker",
            "prepare_frame",
        ),
        "dispeval_ros.core.evaluator": (
            "DEFAULT_CRITERIA",
            "POLICIES",
            "Evaluator",
            "Reference",
        ),
        "dispeval_ros.core.gtfree": (
            "GroundTruthFree",
            "ImagePair",
        ),
        "dispeval_ros.core.lidar_drift": (
            "DriftOptions",
            "DriftSums",
            "coded_estimate",
            "lidar_drift",
        ),
        "dispeval_ros.core.measures": (
            "DEFAULT_MEASURES",
            "HIGHER_IS_BETTER",
            "Scores",
            "parse_measures",
        ),
        "dispeval_ros.core.models": (
            "ModelResult",
            "Reduction",
            "astar_groups",
            "dominates",
            "evaluate_models",
            "front_reduction",
            "interpretation",
            "measure_consistency",
            "middlebury_ranks",
            "pareto_front",
        ),
        "dispeval_ros.core.projection": (
            "CloudFilter",
            "CloudProjection",
            "project_cloud",
        ),
        "dispeval_ros.core.protocols": (
            "PROTOCOLS",
            "FrameData",
            "FrameResult",
            "Protocol",
            "evaluate_frame",
            "get_protocol",
            "summarize_frames",
        ),
        "dispeval_ros.core.temporal": (
            "PairReference",
            "PairScores",
            "PreparedEstimate",
            "TemporalScorer",
        ),
        "dispeval_ros.core.transform_history": ("TransformHistory",),
        "dispeval_ros.core.transforms": (
            "StaticTransform",
            "TransformTree",
        ),
    },
)

if TYPE_CHECKING:
    from dispeval_ros.core.camera import Camera
    from dispeval_ros.core.confidence import (
        ConfidencePreset,
        ConfidenceScorer,
        ConfidenceSums,
        parse_preset,
    )
    from dispeval_ros.core.criteria import (
        CRITERION_SETS,
        CriterionSet,
        Partition,
        VisibilityOptions,
        build_partition,
        standard_partition,
    )
    from dispeval_ros.core.egomotion import (
        EgoMotionOptions,
        FlickerWindow,
        MotionFrame,
        PinholeCamera,
        TemporalSums,
        egomotion_residual,
        flicker,
        prepare_frame,
    )
    from dispeval_ros.core.evaluator import DEFAULT_CRITERIA, POLICIES, Evaluator, Reference
    from dispeval_ros.core.gtfree import GroundTruthFree, ImagePair
    from dispeval_ros.core.lidar_drift import DriftOptions, DriftSums, coded_estimate, lidar_drift
    from dispeval_ros.core.measures import (
        DEFAULT_MEASURES,
        HIGHER_IS_BETTER,
        Scores,
        parse_measures,
    )
    from dispeval_ros.core.models import (
        ModelResult,
        Reduction,
        astar_groups,
        dominates,
        evaluate_models,
        front_reduction,
        interpretation,
        measure_consistency,
        middlebury_ranks,
        pareto_front,
    )
    from dispeval_ros.core.projection import CloudFilter, CloudProjection, project_cloud
    from dispeval_ros.core.protocols import (
        PROTOCOLS,
        FrameData,
        FrameResult,
        Protocol,
        evaluate_frame,
        get_protocol,
        summarize_frames,
    )
    from dispeval_ros.core.temporal import (
        PairReference,
        PairScores,
        PreparedEstimate,
        TemporalScorer,
    )
    from dispeval_ros.core.transform_history import TransformHistory
    from dispeval_ros.core.transforms import StaticTransform, TransformTree

__all__ = [
    "CRITERION_SETS",
    "DEFAULT_CRITERIA",
    "DEFAULT_MEASURES",
    "HIGHER_IS_BETTER",
    "POLICIES",
    "PROTOCOLS",
    "Camera",
    "CloudFilter",
    "CloudProjection",
    "ConfidencePreset",
    "ConfidenceScorer",
    "ConfidenceSums",
    "CriterionSet",
    "DriftOptions",
    "DriftSums",
    "EgoMotionOptions",
    "Evaluator",
    "FlickerWindow",
    "FrameData",
    "FrameResult",
    "GroundTruthFree",
    "ImagePair",
    "ModelResult",
    "MotionFrame",
    "PairReference",
    "PairScores",
    "Partition",
    "PinholeCamera",
    "PreparedEstimate",
    "Protocol",
    "Reduction",
    "Reference",
    "Scores",
    "StaticTransform",
    "TemporalScorer",
    "TemporalSums",
    "TransformHistory",
    "TransformTree",
    "VisibilityOptions",
    "astar_groups",
    "build_partition",
    "coded_estimate",
    "dominates",
    "egomotion_residual",
    "evaluate_frame",
    "evaluate_models",
    "flicker",
    "front_reduction",
    "get_protocol",
    "interpretation",
    "lidar_drift",
    "measure_consistency",
    "middlebury_ranks",
    "pareto_front",
    "parse_measures",
    "parse_preset",
    "prepare_frame",
    "project_cloud",
    "standard_partition",
    "summarize_frames",
]
