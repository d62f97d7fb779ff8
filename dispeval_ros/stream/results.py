"""What the evaluation core returns: a frame's results and a method's counts.

Kept apart from :mod:`~dispeval_ros.stream.core` (which re-exports them) so that it stays short.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dispeval_ros.core import Partition, Scores
from dispeval_ros.core.confidence import ConfidenceSums
from dispeval_ros.core.egomotion import MotionFrame
from dispeval_ros.core.temporal import PairScores
from dispeval_ros.stream.flicker import FlickerInput, FlickerScore
from dispeval_ros.stream.pairs import MethodPairInput, MotionPair, PairInput


@dataclass
class FrameResult:
    """Scores of every method that delivered an estimate for one ground-truth frame."""

    stamp: int
    scores: dict[str, Scores]
    estimate_stamps: dict[str, int]
    problems: list[tuple[str | None, str]] = field(default_factory=list)
    errors: dict[str, np.ndarray] = field(default_factory=dict)
    """With ``error_images``: per method, the absolute error (float32, NaN where not evaluated)."""
    partition: Partition | None = None
    """The criteria of this frame's ground truth (to render error images with criteria)."""
    arrivals: dict[str, int] = field(default_factory=dict)
    """Per method joined with this frame (scored or not): when its estimate arrived (ns, the
    join's arrival clock: a bag's log time, the receipt time live)."""
    sent: dict[str, int] = field(default_factory=dict)
    """Per method in :attr:`arrivals`: its estimate's header stamp (ns)."""
    pairs: dict[str, PairScores] = field(default_factory=dict)
    """With ``temporal``, after :meth:`EvaluationCore.pair`: per method, the pair ending here
    (its earlier frame's stamp: :attr:`pair_previous`)."""
    pair_previous: int | None = None
    motion_pairs: list[MotionPair] = field(default_factory=list)
    """With ``egomotion``: the ego-motion residuals scored with this frame (of its pair, and
    of earlier pairs that waited for the motion source: each names its stamps)."""
    flicker: list[FlickerScore] = field(default_factory=list)
    """With ``flicker``, after :meth:`EvaluationCore.window`: the windows this frame closed
    (each names its first and last stamps; ended early by this frame: the frame before)."""
    confidence: dict[str, ConfidenceSums] = field(default_factory=dict)
    """With ``confidences``: per method scored with its confidence map, this frame's sums."""
    pair_input: PairInput | None = None  # for the pair stage, dropped once it ran
    prepared: dict[str, MethodPairInput] = field(default_factory=dict, repr=False)
    flicker_input: FlickerInput | None = None  # for the flicker stage, dropped once it ran
    flicker_frames: dict[str, MotionFrame] = field(default_factory=dict, repr=False)

    def delays(self) -> dict[str, int]:
        """Per method: arrival minus its estimate's header stamp (ns)."""
        return {method: arrival - self.sent[method] for method, arrival in self.arrivals.items()}


@dataclass
class MethodCounts:
    """Join counts plus frames that were joined but could not be scored."""

    matched: int = 0
    unmatched: int = 0
    dropped: int = 0
    failed: int = 0
