"""The summarizer's transport-free core: accumulate score vectors per sequence, group methods.

Frames are written to the same results database as ``dispeval bag`` in units of ``every_n``
frames as they come (a crash loses at most one unit), and A* Groups with the front reduction
are recomputed after every unit; :meth:`SummarizerCore.finish` writes the last frames, the CSV,
``summary.json`` and ``timing.json``. Nothing accumulated is lost on an orderly shutdown.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dispeval_ros.core import Scores
from dispeval_ros.core.egomotion import TemporalSums
from dispeval_ros.core.lidar_drift import DriftSums
from dispeval_ros.core.objectives import is_pair_measure
from dispeval_ros.core.provenance import provenance_record
from dispeval_ros.core.records import (
    FrameFlicker,
    FrameMotion,
    FramePair,
    FrameScores,
    FrameTiming,
    MatchCounts,
    Problem,
)
from dispeval_ros.core.temporal import PairScores
from dispeval_ros.core.timing import is_timing_measure
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.io.jsonio import write_json
from dispeval_ros.io.store import SUMMARY_JSON, TIMING_JSON, ResultsStore
from dispeval_ros.stream.flicker import FlickerScore
from dispeval_ros.stream.vectors import OK, StatusRecord, format_number
from dispeval_ros.summary import RunSummary, summarize


@dataclass(frozen=True)
class SummarizerConfig:
    """Where results go and how methods are compared."""

    out: Path
    objective_measures: Sequence[str] = ()
    """Empty: the default rule on the measures stored (:func:`default_objective_measures`)."""
    granularity: str = "sequence"
    every_n: int = 10
    resume: bool = False

    def __post_init__(self) -> None:
        if self.every_n < 1:
            raise ConfigurationError(
                f"the summary period must be at least 1 frame, got {self.every_n}"
            )


class RunningTotals:
    """Per-sequence totals over the frames every method delivered, kept as frames arrive.

    A summary from the database re-reads every frame, which grows with the run; this keeps
    the sums of the common frames up to date in O(1) per frame, so a live summary costs the
    same after an hour as after a minute. It answers the questions a summary asks (the
    :class:`~dispeval_ros.summary.ScoreSource` protocol) for per-sequence objectives.
    """

    def __init__(self) -> None:
        self._methods: list[str] = []
        self._measures: list[str] = []
        self._template: Scores | None = None
        self._totals: dict[str, dict[str, np.ndarray]] = {}
        self._common: dict[str, list[int]] = {}
        self._present: dict[str, set[str]] = {}
        self._frames: dict[str, dict[str, int]] = {}

    def add(self, sequence: str, stamp: int, scores: Mapping[str, Scores]) -> None:
        """One frame; it counts only when every method of the sequence delivered it."""
        if self._template is None and scores:
            self._template = next(iter(scores.values()))
            self._measures = list(self._template.measures)
        present = self._present.setdefault(sequence, set())
        counts = self._frames.setdefault(sequence, {})
        for method in scores:
            counts[method] = counts.get(method, 0) + 1
            if method not in self._methods:
                self._methods.append(method)
        if not set(scores) <= present or not present:
            # a method new to the sequence: earlier frames lack it, so none of them is common
            present.update(scores)
            self._totals[sequence] = {}
            self._common[sequence] = []
        if set(scores) != present:
            return
        totals = self._totals[sequence]
        for method, method_scores in scores.items():
            if method in totals:
                totals[method] = totals[method] + method_scores.sums
            else:
                totals[method] = method_scores.sums.copy()
        self._common[sequence].append(int(stamp))

    def sequences(self) -> list[str]:  # noqa: D102 - the ScoreSource protocol
        return list(self._frames)

    def methods(self) -> list[str]:  # noqa: D102
        return list(self._methods)

    def measures(self) -> list[str]:  # noqa: D102
        return list(self._measures)

    def common_stamps(self, sequence: str) -> list[int]:  # noqa: D102
        return list(self._common.get(sequence, []))

    def sequence_scores(  # noqa: D102
        self, sequence: str | None = None, stamps: Collection[int] | None = None
    ) -> dict[str, Scores]:
        template = self._template
        if sequence is None or template is None:
            raise ConfigurationError("running totals are kept per sequence")
        return {
            method: dataclasses.replace(template, sums=sums, quantiles={}, _cache={})
            for method, sums in self._totals.get(sequence, {}).items()
        }

    def frame_scores(self, sequence: str, stamp: int) -> dict[str, Scores]:  # noqa: D102
        raise ConfigurationError(
            "running totals keep no single frames; use per-sequence objectives"
        )

    def match_counts(self, sequence: str) -> dict[str, MatchCounts]:  # noqa: D102
        return {m: MatchCounts(n, 0, 0, 0) for m, n in self._frames.get(sequence, {}).items()}


class SummarizerCore:
    """Accumulate frames (method → Scores per stamp) into sequences; summarise periodically."""

    def __init__(self, config: SummarizerConfig, run_config: Mapping[str, object]) -> None:
        self.config = config
        self.store = ResultsStore.create(config.out, run_config, resume=config.resume)
        # live streams are not kept, so they cannot be hashed: the record says so
        self.provenance = provenance_record(
            run_config, {"streams": "live (messages are not kept, so not hashed)"}
        )
        self.store.set_provenance(self.provenance)
        existing = self.store.sequences()
        self._sequence_index = len(existing)
        self.sequence = self._name(self._sequence_index)
        self._pending: list[FrameScores] = []
        self._timing: list[FrameTiming] = []
        self._pairs: list[FramePair] = []
        self._motion: list[FrameMotion] = []
        self._flicker: list[FrameFlicker] = []
        self._units = len(self.store.done_units(self.sequence))
        self.summary: RunSummary | None = None
        self.frames = 0
        self.totals = RunningTotals()
        self._finished = False

    @staticmethod
    def _name(index: int) -> str:
        return f"sequence_{index:03d}"

    def add(
        self,
        stamp: int,
        scores: Mapping[str, Scores],
        arrivals: Mapping[str, tuple[int, int]] | None = None,
        pairs: Mapping[str, tuple[int, PairScores]] | None = None,
        motion: Mapping[str, tuple[int, TemporalSums]] | None = None,
        *,
        drift: Mapping[str, DriftSums] | None = None,
        flicker: Mapping[str, FlickerScore] | None = None,
    ) -> RunSummary | None:
        """One frame's scores; returns a fresh summary when a unit was just written.

        ``arrivals``: per method, (estimate stamp, arrival) of its estimate (the latency), also
        of an estimate that could not be scored: it was delivered all the same, and ``dispeval
        bag`` keeps its arrival too. Without scores only the arrivals are recorded. ``pairs``:
        per method, the pair ending at this frame (the earlier frame's stamp, its scores), stored
        with the unit as ``dispeval bag --temporal`` stores it; ``motion``: likewise its
        ego-motion residual, and ``drift`` that pair's LiDAR drift; ``flicker``: per method, the
        flicker window closed with it.
        """
        drifts = drift or {}
        self._flicker.extend(
            FrameFlicker(self.sequence, w.start, w.stamp, method, w.frames, w.sums)
            for method, w in (flicker or {}).items()
        )
        self._motion.extend(
            FrameMotion(self.sequence, int(stamp), method, previous, sums, drifts.get(method))
            for method, (previous, sums) in (motion or {}).items()
        )
        self._pairs.extend(
            FramePair(self.sequence, int(stamp), method, previous, pair)
            for method, (previous, pair) in (pairs or {}).items()
        )
        self._timing.extend(
            FrameTiming(self.sequence, int(stamp), method, sent, arrival)
            for method, (sent, arrival) in (arrivals or {}).items()
        )
        if not scores:
            return None
        for method, method_scores in scores.items():
            self._pending.append(FrameScores(self.sequence, int(stamp), method, method_scores))
        self.totals.add(self.sequence, int(stamp), scores)
        self.frames += 1
        if len({f.stamp for f in self._pending}) >= self.config.every_n:
            return self._write_unit()
        return None

    def _write_unit(self) -> RunSummary | None:
        if not self._pending and not self._timing:
            return self.summary
        counts: dict[str, MatchCounts] = {}
        for frame in self._pending:
            previous = counts.get(frame.method, MatchCounts(0, 0, 0, 0))
            counts[frame.method] = MatchCounts(previous.matched + 1, 0, 0, 0)
        unit = f"{self._units:06d}"
        self.store.add_unit(
            self.sequence, unit, self._pending, (), counts, self._timing, self._pairs,
            self._motion, self._flicker,
        )  # fmt: skip
        self._units += 1
        self._pending = []
        self._timing = []
        self._pairs = []
        self._motion = []
        self._flicker = []
        # Live summaries come from the running totals (O(1) per frame); per-frame objectives
        # and timing ones need every frame and so read the database. finish() always does.
        timed = any(
            is_timing_measure(m) or is_pair_measure(m) for m in self.config.objective_measures
        )
        by_sequence = self.config.granularity == "sequence" and not timed
        source = self.totals if by_sequence else self.store
        self.summary = summarize(source, self.config.objective_measures, self.config.granularity)
        return self.summary

    def add_counts(
        self,
        counts: Mapping[str, MatchCounts],
        problems: Sequence[tuple[int | None, str | None, str]] = (),
    ) -> None:
        """Match counts and problems (stamp, method, message) of the current sequence.

        They come from the evaluator (unmatched, dropped, failed; frames it could not score)
        and are stored as a unit of their own, as ``dispeval bag`` stores them with its frames.
        """
        if not counts and not problems:
            return
        rows = [Problem(self.sequence, stamp, method, text) for stamp, method, text in problems]
        self.store.add_unit(self.sequence, f"{self._units:06d}", [], rows, counts)
        self._units += 1

    def new_sequence(self) -> str:
        """Close the current sequence (writing what it holds) and start the next one."""
        self._write_unit()
        self._sequence_index += 1
        self.sequence = self._name(self._sequence_index)
        self._units = 0
        return self.sequence

    def finish(self) -> RunSummary | None:
        """Write what is accumulated, the CSV, ``summary.json``, ``timing.json``; close the store.

        ``timing.json`` (ros2_benchmark's keys) only where latency was recorded, as a bag run.
        """
        if self._finished:
            return self.summary
        self._finished = True
        try:
            self._write_unit()
            if self.store.sequences():
                self.store.export_csv(self.config.out / "frames.csv")
                summary = summarize(
                    self.store, self.config.objective_measures, self.config.granularity
                )
                self.summary = summary
                document = {**summary.to_dict(), "provenance": self.provenance}
                write_json(self.config.out / SUMMARY_JSON, document)
                timing = summary.benchmark_document()
                if timing:  # latency recorded: ros2_benchmark's keys, as a bag run writes them
                    write_json(self.config.out / TIMING_JSON, timing)
        finally:
            self.store.close()
        return self.summary


def group_statuses(summary: RunSummary, sequence: str | None = None) -> list[StatusRecord]:
    """One status per method: its A* group, u1/u2 (group 1), reduced flag, interpretation."""
    chosen = next((s for s in summary.sequences if s.sequence == sequence), None)
    if chosen is None and summary.sequences:
        chosen = summary.sequences[-1]
    models = (
        summary.overall
        if sequence is None and summary.overall is not None
        else (chosen.models if chosen is not None else None)
    )
    if models is None:
        return []
    scope = "all sequences" if models is summary.overall else (chosen.sequence if chosen else "")
    records = []
    for method in models.methods:
        reduction = models.reduction.get(method, {})
        values = [
            ("scope", scope),
            ("group", str(models.groups[method])),
            ("u1", format_number(reduction.get("u1", float("nan")))),
            ("u2", format_number(reduction.get("u2", float("nan")))),
            ("reduced", "true" if method in models.reduced else "false"),
            ("average_rank", format_number(models.middlebury[method])),
            ("interpretation", models.interpretation),
        ]
        message = f"A* group {models.groups[method]}" + (
            " (reduced set)" if method in models.reduced else ""
        )
        records.append(StatusRecord(method, "dispeval/groups", OK, message, tuple(values)))
    return records
