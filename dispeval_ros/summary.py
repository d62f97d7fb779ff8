"""Per-sequence and overall summaries of a results database: scores, A* Groups, reduced set.

Sums such as SZE and BMPRE grow with the number of points, so methods are compared on the
frames that *every* method delivered (the common stamps) only: a method that dropped frames
is not rewarded with smaller sums. Sequence scores are sums of per-frame sums.

Latency and rate (:mod:`~dispeval_ros.core.timing`) are per method over all the frames it
delivered in the sequence (a delay is no sum: delivering fewer frames does not lower it, and
the frames it missed are a measure of their own), so the objective ranked is the number the
latency table shows.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from dispeval_ros.core import ModelResult, Scores, evaluate_models
from dispeval_ros.core.confidence import ConfidenceSums
from dispeval_ros.core.egomotion import TemporalSums
from dispeval_ros.core.lidar_drift import DriftOptions, DriftSums, drift_entry
from dispeval_ros.core.measures import GT_FREE_PREFIX, HIGHER_IS_BETTER, applies
from dispeval_ros.core.objectives import (
    default_objective_measures,
    egomotion_objectives,
    has_points,
    pair_objectives,
    split_egomotion_measures,
    split_pair_measures,
    split_timing_measures,
    timing_objectives,
)
from dispeval_ros.core.records import FrameTiming, MatchCounts
from dispeval_ros.core.temporal import PairScores
from dispeval_ros.core.timing import Timing, benchmark_keys, timing_of
from dispeval_ros.errors import ConfigurationError

GRANULARITIES = ("sequence", "frame")
FLICKER_LABEL = "temporal noise of a static camera, not accuracy"
"""What every flicker output says it is (summary.json, tables, /dispeval/scores' help)."""


@dataclass
class SequenceSummary:
    """One sequence: counts, totals over the common frames, and the models on them."""

    sequence: str
    counts: dict[str, MatchCounts]
    scores: dict[str, Scores]
    common_frames: int
    objectives: list[str]
    models: ModelResult | None
    timing: dict[str, Timing] | None = None
    """Per method, its latency and rate over the sequence; None: no latency recorded."""
    pairs: dict[str, PairScores] | None = None
    """Per method with a pair, its pairs of consecutive frames pooled (``--temporal``); None:
    not recorded (a database older than the pairs table)."""

    motion: dict[str, tuple[int, TemporalSums]] | None = None
    """Per method: its ego-motion pairs and their residual sums pooled (``egomotion``)."""
    drift: dict[str, tuple[int, DriftSums]] | None = None
    """Per method: its LiDAR drift pairs and their sums pooled (``egomotion`` with LiDAR GT);
    None: not recorded (a database older than the drift table)."""

    def drift_dict(self) -> dict[str, Any] | None:
        """The JSON ``lidar_drift`` entry as ``eval --egomotion --json`` writes it, with pairs.

        Each method's entry also holds its ``pairs``; None without any drift (no LiDAR ground
        truth, or not recorded).
        """
        if not self.drift:
            return None
        options = next(iter(self.drift.values()))[1].options
        entry = drift_entry(options or DriftOptions(), {m: s for m, (_, s) in self.drift.items()})
        for method, (pairs, _) in self.drift.items():
            entry["methods"][method]["pairs"] = pairs  # type: ignore[index]
        return entry

    flicker: dict[str, tuple[int, int, TemporalSums]] | None = None
    """Per method: its flicker windows, their frames and their sums pooled (``flicker``)."""

    def flicker_dict(self) -> dict[str, Any] | None:
        """The JSON ``flicker`` entry: what it is, per method its windows and ``gtfree:`` values."""
        return None if self.flicker is None else flicker_entry(self.flicker)

    confidence: dict[str, tuple[int, str, ConfidenceSums]] | None = None
    """Per method with a confidence map: its frames, preset and sums pooled (``confidences``);
    None: not recorded."""

    def confidence_dict(self) -> dict[str, Any] | None:
        """The JSON ``confidence`` entry: per method its frames, preset and curves by criterion.

        The curves' entries are ``eval --confidence``'s (:meth:`ConfidenceSums.summary`).
        """
        if self.confidence is None:
            return None
        return {
            method: {"frames": frames, "preset": preset, "criteria": sums.summary()}
            for method, (frames, preset, sums) in self.confidence.items()
        }

    def egomotion_dict(self) -> dict[str, Any] | None:
        """The JSON ``egomotion`` entry: per method its pairs, values by ``gtfree:`` criterion."""
        if self.motion is None:
            return None
        return {
            method: {
                "pairs": pairs,
                "criteria": {GT_FREE_PREFIX + c: sums.summary(c) for c in sums.criteria},
                "offsets": list(sums.offsets),
            }
            for method, (pairs, sums) in self.motion.items()
        }

    def temporal_dict(self) -> dict[str, Any] | None:
        """The JSON ``temporal`` entry: per method its pairs and values by criterion."""
        if self.pairs is None:
            return None
        return {
            method: {"pairs": scores.pairs, "criteria": scores.to_dict()}
            for method, scores in self.pairs.items()
        }


@dataclass
class RunSummary:
    """Every sequence, and the models over all sequences together."""

    granularity: str
    measures: list[str]
    sequences: list[SequenceSummary]
    overall_objectives: list[str]
    overall: ModelResult | None
    overall_matrix: np.ndarray | None = field(default=None, repr=False)
    """Methods × ``overall_objectives`` (every sequence's objectives side by side)."""
    temporal: str | None = None
    """The temporal preset the run scored pairs under (None: no ``--temporal``)."""
    egomotion: bool = False
    """Whether the run scored the ego-motion residual of its pairs."""
    flicker: bool = False
    """Whether the run scored flicker windows."""
    confidence: bool = False
    """Whether the run scored confidence maps."""

    def benchmark_document(self) -> dict[str, Any]:
        """The timing in ros2_benchmark's result-JSON style: a section per sequence and method.

        Sections are named ``sequence/method`` (theirs are named by test), each holding the
        ``BasicPerformanceMetrics.*`` keys of :func:`~dispeval_ros.core.timing.benchmark_keys`;
        empty where no latency was recorded.
        """
        return {
            f"{s.sequence}/{method}": benchmark_keys(timing)
            for s in self.sequences
            for method, timing in (s.timing or {}).items()
        }

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (NaN left for the JSON writer to turn into null)."""
        return {
            "granularity": self.granularity,
            "objective_measures": self.measures,
            "sequences": [
                {
                    "sequence": s.sequence,
                    "common_frames": s.common_frames,
                    "counts": {m: vars(c) for m, c in s.counts.items()},
                    "scores": {m: sc.to_dict() for m, sc in s.scores.items()},
                    "objectives": s.objectives,
                    "models": s.models.to_dict() if s.models else None,
                    "latency": None
                    if s.timing is None
                    else {m: t.to_dict() for m, t in s.timing.items()},
                    **({"temporal": s.temporal_dict()} if self.temporal else {}),
                    **(
                        {"egomotion": s.egomotion_dict(), "lidar_drift": s.drift_dict()}
                        if self.egomotion
                        else {}
                    ),
                    **({"flicker": s.flicker_dict()} if self.flicker else {}),
                    **({"confidence": s.confidence_dict()} if self.confidence else {}),
                }
                for s in self.sequences
            ],
            "overall": {
                "objectives": self.overall_objectives,
                "models": self.overall.to_dict() if self.overall else None,
            },
        }


def _criteria(scores: Scores) -> list[str]:
    return [c for c in scores.criteria if c not in scores.overlapping]


def _block(
    scores: dict[str, Scores], methods: Sequence[str], measures: Sequence[str], label: str
) -> tuple[list[str], np.ndarray]:
    """Objective names and the methods × objectives block of one set of scores.

    A measure is an objective only on the criteria it is defined on: GT measures on GT
    criteria, GT-free ones (vpe, lrc) on ``gtfree:`` criteria, so the two never mix unless
    both kinds of measure are chosen; and only on criteria with points (:func:`has_points`:
    ``boundary`` of a GT without disparity jumps is no objective, nor a criterion empty in the
    frame of a per-frame objective). Every objective is minimised: higher-is-better measures
    (density) are negated, as :func:`~dispeval_ros.core.objectives.objective_matrix` does.
    """
    criteria = [c for c in _criteria(scores[methods[0]]) if has_points(scores, c)]
    pairs = [(c, m) for c in criteria for m in measures if applies(m, c)]
    names = [f"{c}/{m}{label}" for c, m in pairs]
    signs = np.array([-1.0 if m in HIGHER_IS_BETTER else 1.0 for _, m in pairs])
    block = np.array(
        [[scores[method][c][m] for c, m in pairs] for method in methods], dtype=np.float64
    ).reshape(len(methods), len(pairs))
    return names, block * signs


class ScoreSource(Protocol):
    """What a summary reads: a results database, or the live summarizer's running totals.

    The methods mean what :class:`~dispeval_ros.io.store.ResultsStore`'s do.
    """

    def sequences(self) -> list[str]: ...  # noqa: D102
    def methods(self) -> list[str]: ...  # noqa: D102
    def measures(self) -> list[str]: ...  # noqa: D102
    def common_stamps(self, sequence: str) -> list[int]: ...  # noqa: D102
    def sequence_scores(  # noqa: D102
        self, sequence: str | None = None, stamps: Collection[int] | None = None
    ) -> dict[str, Scores]: ...
    def frame_scores(self, sequence: str, stamp: int) -> dict[str, Scores]: ...  # noqa: D102
    def match_counts(self, sequence: str) -> dict[str, MatchCounts]: ...  # noqa: D102


def sequence_timing(store: object, sequence: str) -> dict[str, Timing] | None:
    """Per method, :func:`~dispeval_ros.core.timing.timing_of` its arrivals in ``sequence``.

    A method counted in the sequence but without any arrival has 0 frames (and its missed
    ones). None where no latency is recorded (an older database, the live running totals).
    """
    reader = getattr(store, "timing", None)
    found: dict[str, list[FrameTiming]] | None = reader(sequence) if reader else None
    if not found:
        return None if found is None else {}
    counts = store.match_counts(sequence)  # type: ignore[attr-defined]
    methods = [*counts, *(m for m in found if m not in counts)]
    result = {}
    for method in methods:
        entries = found.get(method, [])
        missed = counts[method].dropped if method in counts else 0
        result[method] = timing_of(
            [e.estimate_stamp for e in entries], [e.arrival for e in entries], missed
        )
    return result


def run_temporal(store: object) -> str | None:
    """The temporal preset a store's run was configured with (None: none, or live totals)."""
    config = getattr(store, "config", None)
    preset = config().get("temporal") if callable(config) else None
    return str(preset) if preset else None


def sequence_motion(store: object, sequence: str) -> dict[str, tuple[int, TemporalSums]] | None:
    """Per method, its ego-motion pairs in ``sequence`` (None: not recorded, or live totals)."""
    reader = getattr(store, "motion_pairs", None)
    return reader(sequence) if reader else None


def sequence_drift(store: object, sequence: str) -> dict[str, tuple[int, DriftSums]] | None:
    """Per method, its LiDAR drift pairs in ``sequence`` (None: not recorded, or live totals)."""
    reader = getattr(store, "drift_pairs", None)
    return reader(sequence) if reader else None


def flicker_entry(flicker: Mapping[str, tuple[int, int, TemporalSums]]) -> dict[str, Any]:
    """The JSON ``flicker`` entry of ``summary.json`` and ``eval --flicker``.

    The label, and per method (its windows, their frames, pooled sums) the values and sums by
    ``gtfree:`` criterion.
    """
    return {
        "label": FLICKER_LABEL,
        "methods": {
            method: {
                "windows": windows,
                "frames": frames,
                "criteria": {GT_FREE_PREFIX + c: sums.summary(c) for c in sums.criteria},
                "columns": list(sums.columns),
                "sums": {
                    GT_FREE_PREFIX + c: row.tolist()
                    for c, row in zip(sums.criteria, sums.sums, strict=True)
                },
            }
            for method, (windows, frames, sums) in flicker.items()
        },
    }


def sequence_flicker(
    store: object, sequence: str
) -> dict[str, tuple[int, int, TemporalSums]] | None:
    """Per method, its flicker windows in ``sequence`` (None: not recorded, or live totals)."""
    reader = getattr(store, "flicker", None)
    return reader(sequence) if callable(reader) else None


def sequence_confidence(
    store: object, sequence: str
) -> dict[str, tuple[int, str, ConfidenceSums]] | None:
    """Per method, its confidence sums in ``sequence`` (None: not recorded, or live totals)."""
    reader = getattr(store, "confidence", None)
    return reader(sequence) if callable(reader) else None


def sequence_pairs(store: object, sequence: str) -> dict[str, PairScores] | None:
    """Per method, its pairs in ``sequence`` pooled (None: not recorded, or live totals)."""
    reader = getattr(store, "pairs", None)
    return reader(sequence) if reader else None


def _objectives(
    store: ScoreSource,
    sequence: str,
    methods: Sequence[str],
    measures: Sequence[str],
    granularity: str,
) -> tuple[list[str], np.ndarray, dict[str, Scores], int]:
    stamps = store.common_stamps(sequence)
    totals = store.sequence_scores(sequence, stamps=stamps) if stamps else {}
    if not stamps:
        return [], np.empty((len(methods), 0)), totals, 0
    if granularity == "sequence":
        names, block = _block(totals, methods, measures, f" @{sequence}")
        return names, block, totals, len(stamps)
    names, blocks = [], []
    for stamp in stamps:
        frame_names, block = _block(
            store.frame_scores(sequence, stamp), methods, measures, f" @{sequence}:{stamp}"
        )
        names.extend(frame_names)
        blocks.append(block)
    return names, np.hstack(blocks), totals, len(stamps)


def summarize(
    store: ScoreSource,
    measures: Sequence[str] | None = None,
    granularity: str = "sequence",
) -> RunSummary:
    """Models per sequence and overall, objectives per (criterion, sequence) or (criterion, frame).

    ``measures`` empty or None: :func:`default_objective_measures` of the measures stored.
    """
    if granularity not in GRANULARITIES:
        raise ConfigurationError(
            f"objectives must be one of {', '.join(GRANULARITIES)}, got '{granularity}'"
        )
    computed = store.measures()
    measures = measures or default_objective_measures(computed)
    scored, timed = split_timing_measures(measures)
    scored, paired = split_pair_measures(scored)
    scored, moved = split_egomotion_measures(scored)
    unknown = [m for m in scored if computed and m not in computed]
    if unknown:
        raise ConfigurationError(
            f"objective measure(s) {', '.join(unknown)} were not computed; "
            f"computed: {', '.join(computed)}"
        )
    methods = store.methods()
    summaries = []
    all_names: list[str] = []
    all_blocks: list[np.ndarray] = []
    for sequence in store.sequences():
        names, block, totals, common = _objectives(store, sequence, methods, scored, granularity)
        timing = sequence_timing(store, sequence)
        pairs = sequence_pairs(store, sequence)
        motion = sequence_motion(store, sequence)
        if common and timed:
            timing_names, timing_block = timing_objectives(timing, sequence, methods, timed)
            names, block = [*names, *timing_names], np.hstack([block, timing_block])
        if common and paired:
            pair_names, pair_block = pair_objectives(pairs, sequence, methods, paired)
            names, block = [*names, *pair_names], np.hstack([block, pair_block])
        if common and moved:
            moved_names, moved_block = egomotion_objectives(motion, sequence, methods, moved)
            names, block = [*names, *moved_names], np.hstack([block, moved_block])
        present = [m for m in methods if m in totals]
        models = evaluate_models(present, block) if len(present) > 1 and names else None
        summaries.append(
            SequenceSummary(
                sequence,
                store.match_counts(sequence),
                totals,
                common,
                names,
                models,
                timing,
                pairs,
                motion,
                sequence_drift(store, sequence),
                sequence_flicker(store, sequence),
                sequence_confidence(store, sequence),
            )
        )
        if names:
            all_names.extend(names)
            all_blocks.append(block)
    matrix = np.hstack(all_blocks) if all_blocks else None
    overall = None
    if len(summaries) > 1 and matrix is not None and len(methods) > 1:
        overall = evaluate_models(methods, matrix)
    stored = [p.preset.name for s in summaries for p in (s.pairs or {}).values()]
    temporal = run_temporal(store) or (stored[0] if stored else None)  # (live: pairs only)
    config = getattr(store, "config", None)
    egomotion = bool(config().get("egomotion")) if callable(config) else False
    egomotion = egomotion or any(s.motion for s in summaries)
    flicker = bool(config().get("flicker")) if callable(config) else False
    flicker = flicker or any(s.flicker for s in summaries)
    confidence = bool(config().get("confidences")) if callable(config) else False
    confidence = confidence or any(s.confidence for s in summaries)
    return RunSummary(
        granularity,
        list(measures),
        summaries,
        all_names,
        overall,
        matrix,
        temporal,
        egomotion,
        flicker,
        confidence,
    )


def objective_table(
    store: ScoreSource,
    measures: Sequence[str] | None = None,
    granularity: str = "sequence",
) -> tuple[list[str], list[str], np.ndarray]:
    """Methods, objective names and matrix over every sequence, as the overall summary uses.

    The objectives of each sequence come from the frames every method delivered (see
    :func:`summarize`); this is the table ``dispeval models`` compares and exports.
    """
    summary = summarize(store, measures, granularity)
    methods = store.methods()
    if summary.overall_matrix is None:
        return methods, [], np.empty((len(methods), 0))
    return methods, summary.overall_objectives, summary.overall_matrix
