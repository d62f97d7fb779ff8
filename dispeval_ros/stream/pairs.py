"""The pair stage of the evaluation core: temporal measures over consecutive frames of a stream.

Frames of a stream are scored one by one (side by side, possibly), then handed in the join's
order to :class:`PairStage`, which keeps the last of them and scores each method's pair
(previous frame, this frame) with :class:`~dispeval_ros.core.temporal.TemporalScorer`. The
rules, stated once (docs/method.md, "Temporal measures in bags and live"):

- the pair is (the frame the join produced just before, this frame), for every method scored
  on both; the previous frame is always the last frame produced, whatever became of it, so the
  pairs depend only on each two neighbouring frames (a bag cut into units gives the same pairs);
- a method scored on the previous frame but not on this one (no estimate, or a scoring
  problem) ends its run of pairs: one problem line;
- frames further apart than the pair gap (:data:`DEFAULT_PAIR_GAP_NS`, :data:`PAIR_GAP_RULE`)
  are not paired (one problem line per method), nor is a frame whose stamp is not after the
  previous one's (one problem line);
- the ground truth of both frames is used as ``eval --scene --temporal`` uses it (dense GT:
  the pixels with GT in both frames).

Nothing here knows of ROS or files.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from dispeval_ros.core.evaluator import Evaluator, Reference
from dispeval_ros.core.temporal import PairScores, PreparedEstimate, TemporalScorer
from dispeval_ros.errors import DispevalError

DEFAULT_PAIR_GAP_NS = 250_000_000
"""Frames further apart than this (stamps) are not a pair: a camera at 4 Hz or more has its
consecutive frames closer; a longer gap is a lost frame or a pause in the stream."""
PAIR_GAP_RULE = (
    "consecutive ground-truth frames whose stamps are further apart are not paired (a lost "
    "frame or a pause ends the run of pairs)"
)
"""The pair gap's meaning, as every front end's help says it."""


@dataclass(frozen=True)
class PairInput:
    """What one scored frame leaves for its pairs: its reference and each prepared estimate.

    ``reference`` is None when the frame's ground truth could not be scored; ``estimates``
    holds the methods scored on the frame.
    """

    stamp: int
    reference: Reference | None
    estimates: Mapping[str, PreparedEstimate]


@dataclass(frozen=True)
class PairOutcome:
    """The pairs ending at one frame: method → scores, the previous frame's stamp, problems."""

    previous: int | None
    scores: dict[str, PairScores]
    problems: list[tuple[str | None, str]]


def no_pair(method: str, previous: int, stamp: int, reason: str) -> str:
    """``sgbm: no pair 100 → 300: …``, the wording of ``eval --scene --temporal``'s gaps."""
    return f"{method}: no pair {previous} → {stamp}: {reason}"


class PairStage:
    """Keeps the last frame of a stream and scores the pairs ending at each next frame.

    Not thread-safe: call :meth:`add` from one thread, in the join's order of the frames.
    """

    def __init__(self, evaluator: Evaluator, preset: str, gap_ns: int = DEFAULT_PAIR_GAP_NS):
        self.scorer = TemporalScorer(evaluator, preset=preset)
        self.gap_ns = gap_ns
        self._previous: PairInput | None = None

    def prepare(
        self, estimate: object, est_range: tuple[float, float] | None, est_offset: float
    ) -> PreparedEstimate:
        """One estimate made ready for both pairs it is in (any thread)."""
        import numpy as np

        return self.scorer.prepare(np.asarray(estimate), est_range=est_range, est_offset=est_offset)

    def add(self, frame: PairInput) -> PairOutcome:
        """The pairs (previous frame, ``frame``) of every method; ``frame`` becomes the previous."""
        previous, self._previous = self._previous, frame
        if previous is None:
            return PairOutcome(None, {}, [])
        stamp, before = frame.stamp, previous.stamp
        methods = list(previous.estimates)
        problems: list[tuple[str | None, str]] = []
        if stamp <= before:
            reason = f"its stamp is not after the previous frame's ({before}): no pair with it"
            problems.append((None, f"frame at {stamp}: {reason}"))
            return PairOutcome(before, {}, problems)
        gap = stamp - before
        scores: dict[str, PairScores] = {}
        for method in methods:
            if method not in frame.estimates or frame.reference is None:
                problems.append(
                    (method, no_pair(method, before, stamp, f"{method} not scored at {stamp}"))
                )
            elif gap > self.gap_ns:
                reason = (
                    f"the frames are {gap / 1e6:g} ms apart, more than the pair gap "
                    f"{self.gap_ns / 1e6:g} ms"
                )
                problems.append((method, no_pair(method, before, stamp, reason)))
        pairable = [m for m in methods if m in frame.estimates and frame.reference is not None]
        if gap > self.gap_ns or not pairable or previous.reference is None:
            return PairOutcome(before, scores, problems)
        assert frame.reference is not None
        try:
            pair = self.scorer.pair(previous.reference, frame.reference)
        except DispevalError as error:
            problems.extend((m, no_pair(m, before, stamp, str(error))) for m in pairable)
            return PairOutcome(before, scores, problems)
        for method in pairable:
            try:
                scores[method] = self.scorer.score(
                    pair, previous.estimates[method], frame.estimates[method]
                )
            except DispevalError as error:
                problems.append((method, no_pair(method, before, stamp, str(error))))
        return PairOutcome(before, scores, problems)
