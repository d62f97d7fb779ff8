"""dispeval_ros: judge stereo correspondence methods by their disparity maps.

Set-partition evaluation criteria, the depth-aware SZE and BMPRE measures beside the classic
ones, and Pareto-dominance models (A*, A* Groups, front reduction). The public API::

    from dispeval_ros import Evaluator, Camera
    ev = Evaluator(criteria=("all", "visibility", "depth"))
    scores = ev.score(gt, est, camera=Camera(f=721.5, baseline=0.54))
    scores["interior"]["sze"], scores["interior"]["n"]
"""

from typing import TYPE_CHECKING

from dispeval_ros.errors import DispevalError
from dispeval_ros.lazy import lazy_exports
from dispeval_ros.version import __version__

if TYPE_CHECKING:
    from dispeval_ros.core import (
        PROTOCOLS,
        Camera,
        Evaluator,
        GroundTruthFree,
        ImagePair,
        ModelResult,
        Partition,
        Protocol,
        Reference,
        Scores,
        astar_groups,
        evaluate_frame,
        evaluate_models,
        front_reduction,
        measure_consistency,
        middlebury_ranks,
        pareto_front,
        summarize_frames,
    )

__all__ = [
    "PROTOCOLS",
    "Camera",
    "DispevalError",
    "Evaluator",
    "GroundTruthFree",
    "ImagePair",
    "ModelResult",
    "Partition",
    "Protocol",
    "Reference",
    "Scores",
    "__version__",
    "astar_groups",
    "evaluate_frame",
    "evaluate_models",
    "front_reduction",
    "measure_consistency",
    "middlebury_ranks",
    "pareto_front",
    "summarize_frames",
]

# the evaluation names load numba and OpenCV: from ``dispeval_ros.core`` on first use, not with
# ``import dispeval_ros`` (DispevalError and __version__, bound above, never reach the table)
__getattr__, __dir__ = lazy_exports(globals(), {"dispeval_ros.core": __all__})
