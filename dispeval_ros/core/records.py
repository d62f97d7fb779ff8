"""Result records: what a scored frame, a problem and a method's match counts are.

Plain frozen dataclasses, kept below storage so that the streaming, offline and summary
layers share them without importing the SQLite module (:mod:`dispeval_ros.io.store` stores
them; nothing here imports numpy or numba).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from dispeval_ros.core.confidence import ConfidenceSums
    from dispeval_ros.core.egomotion import TemporalSums
    from dispeval_ros.core.lidar_drift import DriftSums
    from dispeval_ros.core.measures import Scores
    from dispeval_ros.core.temporal import PairScores

__all__ = [
    "FrameFlicker",
    "FrameMotion",
    "FramePair",
    "FrameScores",
    "FrameTiming",
    "MatchCounts",
    "PooledConfidence",
    "Problem",
]


@dataclass(frozen=True)
class FrameScores:
    """The scores of one method on one frame (``stamp`` in nanoseconds)."""

    sequence: str
    stamp: int
    method: str
    scores: Scores


@dataclass(frozen=True)
class FrameTiming:
    """When one method's estimate for one ground-truth frame arrived (nanoseconds).

    ``stamp``: the ground-truth frame's (as in :class:`FrameScores`); ``estimate_stamp``: the
    estimate's header stamp; ``arrival``: a bag's log time, the receipt time live. Kept for
    every estimate joined with a frame, scored or not (it was delivered either way).
    """

    sequence: str
    stamp: int
    method: str
    estimate_stamp: int
    arrival: int

    @property
    def delay(self) -> int:
        """Arrival minus the estimate's header stamp (ns): how late the map came."""
        return self.arrival - self.estimate_stamp


@dataclass(frozen=True)
class FramePair:
    """One method's pair measures of two consecutive GT frames (stamps in nanoseconds).

    ``stamp``: the later frame's (the pair belongs to the unit that keeps it); ``previous``:
    the earlier frame's.
    """

    sequence: str
    stamp: int
    method: str
    previous: int
    scores: PairScores


@dataclass(frozen=True)
class FrameMotion:
    """One method's ego-motion residual sums of two consecutive frames (as :class:`FramePair`)."""

    sequence: str
    stamp: int
    method: str
    previous: int
    sums: TemporalSums
    drift: DriftSums | None = None
    """The LiDAR drift of the same pair (stored in its own table; None: not scored)."""


@dataclass(frozen=True)
class FrameFlicker:
    """One method's flicker sums over one window of ``frames`` frames, ``start`` to ``stamp``."""

    sequence: str
    start: int
    stamp: int
    method: str
    frames: int
    sums: TemporalSums


@dataclass(frozen=True)
class PooledConfidence:
    """One method's confidence sums pooled over ``frames`` frames, ``start`` to ``stamp``.

    A unit of work stores one per method (the sums of its frames added: exact, as the curves
    of the sequence are those of its rows added); ``preset`` is the convention they were read in.
    """

    sequence: str
    start: int
    stamp: int
    method: str
    frames: int
    preset: str
    sums: ConfidenceSums


@dataclass(frozen=True)
class Problem:
    """A per-frame problem worth reporting (decode error, size mismatch…), kept with the unit."""

    sequence: str
    stamp: int | None
    method: str | None
    message: str


@dataclass(frozen=True)
class MatchCounts:
    """How a method's estimates met the ground truth: matched, unmatched, dropped, failed."""

    matched: int
    unmatched: int
    dropped: int
    failed: int
