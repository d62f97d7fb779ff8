"""A unit's database rows, made without a database (so a worker can make them for a writer)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from dispeval_ros.core.records import (
    FrameFlicker,
    FrameMotion,
    FramePair,
    FrameScores,
    FrameTiming,
    MatchCounts,
    PooledConfidence,
    Problem,
)
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.io.store.confidence import confidence_rows
from dispeval_ros.io.store.flicker import flicker_rows
from dispeval_ros.io.store.pairs import drift_rows, motion_rows, pair_rows
from dispeval_ros.io.store.schema import _BLOB, _Layout


@dataclass(frozen=True)
class PreparedUnit:
    """A unit's database rows, made without a database (by a worker) for a writer to add."""

    sequence: str
    unit: str
    layout: _Layout | None
    frame_rows: list[tuple[object, ...]]
    methods: list[str]
    criteria: dict[str, bool]
    problem_rows: list[tuple[object, ...]]
    count_rows: list[tuple[object, ...]]
    timing_rows: list[tuple[object, ...]] = field(default_factory=list)
    pair_rows: list[tuple[object, ...]] = field(default_factory=list)
    motion_rows: list[tuple[object, ...]] = field(default_factory=list)
    drift_rows: list[tuple[object, ...]] = field(default_factory=list)
    flicker_rows: list[tuple[object, ...]] = field(default_factory=list)
    confidence_rows: list[tuple[object, ...]] = field(default_factory=list)

    @property
    def frames(self) -> int:
        """How many (frame, method) scores the unit holds."""
        return len({(row[1], row[2]) for row in self.frame_rows})


def prepare_unit(
    sequence: str,
    unit: str,
    frames: Sequence[FrameScores],
    problems: Sequence[Problem] = (),
    counts: Mapping[str, MatchCounts] | None = None,
    timing: Sequence[FrameTiming] = (),
    pairs: Sequence[FramePair] = (),
    motion: Sequence[FrameMotion] = (),
    flicker: Sequence[FrameFlicker] = (),
    confidence: Sequence[PooledConfidence] = (),
) -> PreparedUnit:
    """The rows :meth:`ResultsStore.add_unit` writes for a unit (checked: one sequence, no twins)."""
    layout = _unit_layout(unit, frames)
    frame_rows, methods, criteria = _frame_rows(sequence, unit, frames, layout)
    problem_rows: list[tuple[object, ...]] = []
    for position, problem in enumerate(problems):
        if problem.sequence != sequence:
            raise ValueError(
                f"unit '{unit}' of {sequence} holds a problem of sequence {problem.sequence}"
            )
        stamp = None if problem.stamp is None else int(problem.stamp)
        problem_rows.append((sequence, unit, position, stamp, problem.method, problem.message))
    count_rows: list[tuple[object, ...]] = [
        (sequence, method, sequence, c.matched, c.unmatched, c.dropped, c.failed)
        for method, c in (counts or {}).items()
    ]
    timing_rows: list[tuple[object, ...]] = []
    for entry in timing:
        if entry.sequence != sequence:
            raise ValueError(f"unit '{unit}' of {sequence} holds a time of {entry.sequence}")
        timing_rows.append(
            (
                sequence,
                int(entry.stamp),
                entry.method,
                int(entry.estimate_stamp),
                int(entry.arrival),
            )
        )
    return PreparedUnit(
        sequence,
        unit,
        layout,
        frame_rows,
        methods,
        criteria,
        problem_rows,
        count_rows,
        timing_rows,
        pair_rows(sequence, unit, pairs),
        motion_rows(sequence, unit, motion),
        drift_rows(sequence, unit, motion),
        flicker_rows(sequence, unit, flicker),
        confidence_rows(sequence, unit, confidence),
    )


def _unit_layout(unit: str, frames: Sequence[FrameScores]) -> _Layout | None:
    """The layout the unit's frames share (None without frames); a mix is an error."""
    if not frames:
        return None
    layout = _Layout.of(frames[0].scores)
    for frame in frames[1:]:
        scores = frame.scores
        if (
            tuple(scores.measures) != layout.measures
            or scores.policy != layout.policy
            or not np.array_equal(scores.thresholds, layout.thresholds)
        ):
            difference = _Layout.of(scores).difference(layout)
            raise ConfigurationError(f"unit '{unit}' mixes scores of different {difference}")
    return layout


def _frame_rows(
    sequence: str, unit: str, frames: Sequence[FrameScores], layout: _Layout | None
) -> tuple[list[tuple[object, ...]], list[str], dict[str, bool]]:
    """The frames table rows of a unit, its methods and its criteria (first-seen order)."""
    rows: list[tuple[object, ...]] = []
    methods: dict[str, None] = {}
    criteria: dict[str, bool] = {}
    seen: set[tuple[int, str]] = set()
    if layout is None:
        return rows, [], criteria
    width, names, isnan = len(layout.fields), layout.measures, math.isnan
    for frame in frames:
        stamp, method, scores = int(frame.stamp), str(frame.method), frame.scores
        if frame.sequence != sequence:
            raise ValueError(f"unit '{unit}' of {sequence} holds a frame of {frame.sequence}")
        if (stamp, method) in seen:
            raise ValueError(f"unit '{unit}' of {sequence} holds {method} at {stamp} twice")
        seen.add((stamp, method))
        sums = np.ascontiguousarray(scores.sums, dtype=_BLOB)
        if sums.shape != (len(scores.criteria), width):
            raise ValueError(
                f"{method} at {stamp}: sums of shape {sums.shape}, expected "
                f"({len(scores.criteria)}, {width})"
            )
        relative = int(bool(scores.relative))
        methods.setdefault(method, None)
        for index, criterion in enumerate(scores.criteria):
            criteria.setdefault(criterion, criterion in scores.overlapping)
            values = scores[criterion]
            # NaN is stored as NULL (SQLite has no NaN) and read back as NaN
            measures = [None if isnan(v) else v for v in map(values.__getitem__, names)]
            rows.append(
                (sequence, stamp, method, criterion, _sql_float(values["n"]), *measures,
                 sums[index].tobytes(), relative)
            )  # fmt: skip
    return rows, list(methods), criteria


def _sql_float(value: float) -> float | None:
    """NaN is stored as NULL (SQLite has no NaN) and read back as NaN."""
    value = float(value)
    return None if math.isnan(value) else value
