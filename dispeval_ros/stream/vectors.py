"""Score vectors as transport-free records: diagnostics statuses and fixed-order number vectors.

A ROS or DDS front end turns a :class:`StatusRecord` into a ``diagnostic_msgs/DiagnosticStatus``
and a vector into a ``std_msgs/Float64MultiArray`` without knowing anything about scoring.
Numbers are written with ``repr`` so they read back exactly; each criterion also carries its
raw accumulator row (``criterion/sums``) so a summarizer rebuilds the exact :class:`Scores`
(sequence totals are sums of sums, never averages of means).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from dispeval_ros.core import Scores, registry
from dispeval_ros.core.measures import (
    GT_FREE_PREFIX,
    SUM_FIELDS,
    applies,
)
from dispeval_ros.errors import InputError
from dispeval_ros.stream.alarms import DELAY_ALARM, ERROR, OK, WARN, AlarmThresholds

if TYPE_CHECKING:
    from dispeval_ros.core.egomotion import TemporalSums
    from dispeval_ros.core.lidar_drift import DriftSums
    from dispeval_ros.core.temporal import PairScores
    from dispeval_ros.stream.core import FrameResult
    from dispeval_ros.stream.flicker import FlickerScore

SUMS_KEY = "sums"
PROBLEM_KEY = "_problem"
"""Key of the one value of an ERROR status that reports a frame which could not be scored."""
GROUND_TRUTH = "ground_truth"
"""Status name of problems with the ground truth (no method could be scored on that frame)."""
ESTIMATE_STAMP_KEY = "_estimate_stamp"
ARRIVAL_KEY = "_arrival"
"""When the estimate arrived at the evaluator (ns, the stamps' clock): receipt live, log time
replayed from a bag."""
DELAY_KEY = "_delay_ms"
"""Arrival minus the estimate's header stamp, in ms (for a reader of the diagnostics)."""
PAIR_PREFIX = "temporal/"
"""The pair measures of the pair ending at the frame: ``temporal/CRITERION/MEASURE`` (with
``temporal``), never read as the frame's own criteria."""
PAIR_SUMS_KEY = "pair_sums"
"""``temporal/CRITERION/pair_sums``: the pair's raw sums, so a summarizer pools them exactly."""
PAIR_PREVIOUS_KEY = "_pair_previous"
"""The stamp (ns) of the pair's earlier frame."""
PAIR_META = ("_pair_thresholds", "_pair_policy", "_pair_preset")
MOTION_PREFIX = "egomotion/"
"""The ego-motion residual of that pair: ``egomotion/gtfree:CRITERION/VALUE`` (ground-truth
free, so on ``gtfree:`` criteria), its sums ``.../motion_sums``, ``_motion_offset`` (px) and
``_motion_thresholds``; the earlier frame is :data:`PAIR_PREVIOUS_KEY`'s."""
MOTION_SUMS_KEY = "motion_sums"
MOTION_META = ("_motion_thresholds", "_motion_offset")
DRIFT_KEY_PREFIX = "lidar_drift/"
"""The LiDAR drift of that pair (LiDAR GT): ``lidar_drift/drift:CRITERION/VALUE`` (on the
``drift:`` criteria: temporal noise, never accuracy), its sums ``.../drift_sums`` and
:data:`DRIFT_META` (thresholds, missing policy, hidden test ``W,G``)."""
DRIFT_SUMS_KEY = "drift_sums"
DRIFT_META = ("_drift_thresholds", "_drift_policy", "_drift_visibility")
FLICKER_PREFIX = "flicker/"
"""The flicker window that closed with this frame (``flicker``): ``flicker/gtfree:CRITERION/
VALUE`` (temporal noise of a static camera, not accuracy), its sums ``.../flicker_sums``, and
``_flicker_start``, ``_flicker_stamp`` (its first and last frames), ``_flicker_frames``,
``_flicker_thresholds``."""
FLICKER_SUMS_KEY = "flicker_sums"
FLICKER_META = ("_flicker_start", "_flicker_stamp", "_flicker_frames", "_flicker_thresholds")
META_KEYS = (
    "_policy", "_relative", "_thresholds", "_overlapping", ESTIMATE_STAMP_KEY, ARRIVAL_KEY,
    DELAY_KEY,
)  # fmt: skip


@dataclass(frozen=True)
class StatusRecord:
    """One diagnostic status: a method's scores on one frame (or a model result)."""

    name: str
    hardware_id: str
    level: int
    message: str
    values: tuple[tuple[str, str], ...]


def format_number(value: float) -> str:
    """Shortest text that reads back to exactly the same float (``nan``, ``inf`` as such)."""
    return repr(float(value))


def scores_status(
    method: str,
    topic: str,
    scores: Scores,
    alarms: AlarmThresholds | None = None,
    estimate_stamp: int | None = None,
    arrival: int | None = None,
    pair: tuple[int, PairScores] | None = None,
    motion: tuple[int, TemporalSums] | None = None,
    drift: DriftSums | None = None,
) -> StatusRecord:
    """The status of one method on one frame: every ``criterion/measure`` plus raw sums.

    With ``arrival`` (and ``estimate_stamp``): when the estimate arrived and its delay, so a
    summarizer stores the latency as ``dispeval bag`` does (:func:`arrival_of`). With ``pair``
    (the earlier frame's stamp, the pair's scores): the pair measures (:data:`PAIR_PREFIX`);
    with ``motion`` (the same stamp, the residual's sums): :data:`MOTION_PREFIX`'s keys;
    with ``drift`` (that pair's LiDAR drift): :data:`DRIFT_KEY_PREFIX`'s.
    """
    values: list[tuple[str, str]] = []
    level = OK
    worst = ""
    for criterion in scores.criteria:
        table = scores[criterion]
        for measure, value in table.items():
            if not applies(measure, criterion):
                continue  # GT measures on gtfree: criteria and vice versa: always NaN
            key = f"{criterion}/{measure}"
            values.append((key, format_number(value)))
            if alarms is not None:
                found = alarms.level(key, value)
                if found > level:
                    level, worst = found, f"{key} = {value:.4g}"
        row = scores.sums[scores.criteria.index(criterion)]
        values.append((f"{criterion}/{SUMS_KEY}", " ".join(format_number(v) for v in row)))
    values.append(("_policy", scores.policy))
    values.append(("_relative", "1" if scores.relative else "0"))
    values.append(("_thresholds", " ".join(format_number(t) for t in scores.thresholds)))
    values.append(("_overlapping", " ".join(scores.overlapping)))
    if pair is not None:
        values.extend(pair_values(*pair))
    if motion is not None:
        values.extend(motion_values(*motion, with_previous=pair is None))
    if drift is not None:
        values.extend(drift_values(drift))
    delay = _timing_values(values, estimate_stamp, arrival)
    if delay is not None:
        found = OK if alarms is None else alarms.level(DELAY_ALARM, delay)
        if found > level:
            level, worst = found, f"delay {delay:.4g} ms"
    message = {OK: "ok", WARN: f"warning: {worst}", ERROR: f"error: {worst}"}[level]
    return StatusRecord(method, topic, level, message, tuple(values))


def pair_values(previous: int, pair: PairScores) -> list[tuple[str, str]]:
    """The keys of a pair's measures and sums (read back by :func:`pair_from_status`)."""
    values: list[tuple[str, str]] = []
    for criterion, row in zip(pair.criteria, pair.sums, strict=True):
        for measure, value in pair[criterion].items():
            values.append((f"{PAIR_PREFIX}{criterion}/{measure}", format_number(value)))
        text = " ".join(format_number(v) for v in row)
        values.append((f"{PAIR_PREFIX}{criterion}/{PAIR_SUMS_KEY}", text))
    thresholds = " ".join(format_number(t) for t in pair.thresholds)
    meta = (thresholds, pair.policy, pair.preset.name)
    return [*values, (PAIR_PREVIOUS_KEY, str(int(previous))), *zip(PAIR_META, meta, strict=True)]


def _criterion_values(
    prefix: str, sums_key: str, sums: TemporalSums | DriftSums
) -> list[tuple[str, str]]:
    """Per criterion, ``PREFIXCRITERION/VALUE`` of its summary and ``.../SUMS_KEY`` of its row."""
    values: list[tuple[str, str]] = []
    for criterion, row in zip(sums.criteria, sums.sums, strict=True):
        name = f"{prefix}{criterion}/"
        values.extend((name + k, format_number(v)) for k, v in sums.summary(criterion).items())
        values.append((name + sums_key, " ".join(format_number(v) for v in row)))
    return values


def _criterion_sums(
    values: Sequence[tuple[str, str]], prefix: str, sums_key: str
) -> tuple[list[str], list[str]]:
    """The criteria of the ``PREFIXCRITERION/SUMS_KEY`` keys, in order, and their sums' texts."""
    suffix = "/" + sums_key
    found = [(k, v) for k, v in values if k.startswith(prefix) and k.endswith(suffix)]
    return [k[len(prefix) : -len(suffix)] for k, _ in found], [v for _, v in found]


def motion_values(
    previous: int, sums: TemporalSums, with_previous: bool = True
) -> list[tuple[str, str]]:
    """The keys of a pair's ego-motion residual (read back by :func:`motion_from_status`)."""
    values = _criterion_values(MOTION_PREFIX + GT_FREE_PREFIX, MOTION_SUMS_KEY, sums)
    values.append((MOTION_META[0], " ".join(format_number(t) for t in sums.thresholds)))
    values.append((MOTION_META[1], format_number(sums.offsets[0])))
    return values + ([(PAIR_PREVIOUS_KEY, str(int(previous)))] if with_previous else [])


def motion_from_status(values: Sequence[tuple[str, str]]) -> tuple[int, TemporalSums] | None:
    """``(earlier frame's stamp, ego-motion sums)`` of a status with them, else None."""
    from dispeval_ros.core.egomotion import TemporalSums

    table = dict(values)
    if MOTION_META[1] not in table:
        return None
    criteria, texts = _criterion_sums(values, MOTION_PREFIX + GT_FREE_PREFIX, MOTION_SUMS_KEY)
    try:
        thresholds = [float(t) for t in table[MOTION_META[0]].split()]
        sums = np.array([[float(v) for v in text.split()] for text in texts])
        offset, previous = float(table[MOTION_META[1]]), int(table[PAIR_PREVIOUS_KEY])
        return previous, TemporalSums.of_pair(criteria, thresholds, sums, offset)
    except (KeyError, ValueError):
        raise InputError("the diagnostic status has malformed ego-motion keys") from None


def drift_values(drift: DriftSums) -> list[tuple[str, str]]:
    """The keys of a pair's LiDAR drift (read back by :func:`drift_from_status`)."""
    from dispeval_ros.core.lidar_drift import PREFIX

    values = _criterion_values(DRIFT_KEY_PREFIX + PREFIX, DRIFT_SUMS_KEY, drift)
    options = drift.options
    meta = (
        " ".join(format_number(t) for t in drift.thresholds),
        "" if options is None else options.missing,
        "" if options is None else str(options.visibility),
    )
    return values + list(zip(DRIFT_META, meta, strict=True))


def drift_from_status(values: Sequence[tuple[str, str]]) -> DriftSums | None:
    """The LiDAR drift sums of a status with them, else None (its pair: the residual's)."""
    from dispeval_ros.core.lidar_drift import PREFIX, DriftSums

    table = dict(values)
    if DRIFT_META[0] not in table:
        return None
    criteria, texts = _criterion_sums(values, DRIFT_KEY_PREFIX + PREFIX, DRIFT_SUMS_KEY)
    try:
        thresholds, policy, visibility = (table[key] for key in DRIFT_META)
        sums = np.array([float(v) for text in texts for v in text.split()])
        levels = [float(t) for t in thresholds.split()]
        return DriftSums.restored(criteria, sums, policy, visibility, levels)
    except (KeyError, ValueError):
        raise InputError("the diagnostic status has malformed LiDAR drift keys") from None


def read_pairs(
    record: StatusRecord,
    pairs: dict[str, tuple[int, PairScores]],
    motion: dict[str, tuple[int, TemporalSums]],
    *,
    drift: dict[str, DriftSums] | None = None,
    flicker: dict[str, FlickerScore] | None = None,
) -> None:
    """Add a method status's pair, residual, drift and flicker window, where it has them.

    What every summarizer reads of a status beside its scores (:func:`scores_from_status`).
    """
    if drift is not None:
        found = drift_from_status(record.values)
        if found is not None:
            drift[record.name] = found
    pair = pair_from_status(record.values)
    if pair is not None:
        pairs[record.name] = pair
    moved = motion_from_status(record.values)
    if moved is not None:
        motion[record.name] = moved
    window = flicker_from_status(record.name, record.values)
    if window is not None and flicker is not None:
        flicker[record.name] = window


def flicker_values(window: FlickerScore) -> list[tuple[str, str]]:
    """The keys of a flicker window (read back by :func:`flicker_from_status`)."""
    sums = window.sums
    values = _criterion_values(FLICKER_PREFIX + GT_FREE_PREFIX, FLICKER_SUMS_KEY, sums)
    meta = (str(window.start), str(window.stamp), str(window.frames),
            " ".join(format_number(t) for t in sums.thresholds))  # fmt: skip
    return [*values, *zip(FLICKER_META, meta, strict=True)]


def flicker_from_status(method: str, values: Sequence[tuple[str, str]]) -> FlickerScore | None:
    """The flicker window a status carries, else None."""
    from dispeval_ros.io.store.flicker import restored_flicker
    from dispeval_ros.stream.flicker import FlickerScore

    table = dict(values)
    if FLICKER_META[0] not in table:
        return None
    criteria, texts = _criterion_sums(values, FLICKER_PREFIX + GT_FREE_PREFIX, FLICKER_SUMS_KEY)
    try:
        first, last, frames, levels = (table[key] for key in FLICKER_META)
        sums = np.array([[float(v) for v in text.split()] for text in texts])
        restored = restored_flicker(criteria, [float(t) for t in levels.split()], sums)
        return FlickerScore(method, int(first), int(last), int(frames), restored)
    except (KeyError, ValueError):
        raise InputError("the diagnostic status has malformed flicker keys") from None


def pair_from_status(values: Sequence[tuple[str, str]]) -> tuple[int, PairScores] | None:
    """``(earlier frame's stamp, pair scores)`` of a status with a pair, else None."""
    from dispeval_ros.core.temporal import PairScores

    table = dict(values)
    if PAIR_PREVIOUS_KEY not in table or not any(key in table for key in PAIR_META):
        return None  # no pair, or only an ego-motion residual's (egomotion without temporal)
    suffix = "/" + PAIR_SUMS_KEY
    criteria = [k[len(PAIR_PREFIX) : -len(suffix)] for k, _ in values if k.endswith(suffix)]
    try:
        thresholds, policy, preset = (table[key] for key in PAIR_META)
        sums = np.array(
            [[float(v) for v in table[f"{PAIR_PREFIX}{c}{suffix}"].split()] for c in criteria]
        )
        previous = int(table[PAIR_PREVIOUS_KEY])
        levels = [float(t) for t in thresholds.split()]
        return previous, PairScores.restored(criteria, sums, levels, policy, preset)
    except (KeyError, ValueError):
        raise InputError("the diagnostic status has malformed temporal pair keys") from None


def result_statuses(
    result: FrameResult, topics: Mapping[str, str], alarms: AlarmThresholds | None = None
) -> list[StatusRecord]:
    """The status of each method scored on a frame, with its latency and its pair, if any."""
    previous = result.pair_previous
    here = [p for p in result.motion_pairs if p.stamp == result.stamp]
    motion = {p.method: (p.previous, p.sums) for p in here}
    drift = {p.method: p.drift for p in here}
    statuses = [
        scores_status(
            method,
            topics[method],
            scores,
            alarms,
            result.estimate_stamps.get(method),
            result.arrivals.get(method),
            None
            if previous is None or method not in result.pairs
            else (previous, result.pairs[method]),
            motion.get(method),
            drift.get(method),
        )
        for method, scores in result.scores.items()
    ]
    windows = {w.method: w for w in result.flicker}  # (one per method and frame at most)
    return [
        dataclasses.replace(s, values=(*s.values, *flicker_values(windows[s.name])))
        if s.name in windows
        else s
        for s in statuses
    ] + [  # a window closed by its method's missing frame, or by the end of the stream
        StatusRecord(m, topics[m], OK, "flicker window", tuple(flicker_values(w)))
        for m, w in windows.items()
        if m not in result.scores
    ]


def window_only(record: StatusRecord) -> bool:
    """Whether a status carries a flicker window and no scores (see :func:`result_statuses`)."""
    keys = [key for key, _ in record.values]
    return FLICKER_META[0] in keys and not any(k.endswith("/" + SUMS_KEY) for k in keys)


def _timing_values(
    values: list[tuple[str, str]], estimate_stamp: int | None, arrival: int | None
) -> float | None:
    """Append the estimate stamp, arrival and delay keys; returns the delay (ms) if known."""
    if estimate_stamp is None:
        return None
    values.append((ESTIMATE_STAMP_KEY, str(int(estimate_stamp))))
    if arrival is None:
        return None
    delay = (int(arrival) - int(estimate_stamp)) / 1e6
    values.append((ARRIVAL_KEY, str(int(arrival))))
    values.append((DELAY_KEY, format_number(delay)))
    return delay


def arrivals_of(record: StatusRecord) -> dict[str, tuple[int, int]]:
    """Method → (estimate stamp, arrival) in a method or problem status (none: empty)."""
    if record.name != GROUND_TRUTH:
        found = arrival_of(record.values)
        return {} if found is None else {record.name: found}
    table = dict(record.values)
    arrivals = {}
    for key, sent in table.items():
        name, _, leaf = key.rpartition("/")
        arrival = table.get(f"{name}/{ARRIVAL_KEY}")
        if leaf == ESTIMATE_STAMP_KEY and arrival is not None:
            found = arrival_of(((ESTIMATE_STAMP_KEY, sent), (ARRIVAL_KEY, arrival)))
            if found is not None:
                arrivals[name] = found
    return arrivals


def arrival_of(values: Sequence[tuple[str, str]]) -> tuple[int, int] | None:
    """``(estimate stamp, arrival)`` of a status of :func:`scores_status`, None without them."""
    table = dict(values)
    if ESTIMATE_STAMP_KEY not in table or ARRIVAL_KEY not in table:
        return None
    try:
        return int(table[ESTIMATE_STAMP_KEY]), int(table[ARRIVAL_KEY])
    except ValueError:
        raise InputError(
            f"the diagnostic status has a malformed {ESTIMATE_STAMP_KEY} or {ARRIVAL_KEY}"
        ) from None


def scores_from_status(
    values: Sequence[tuple[str, str]], measures: Sequence[str] | None = None
) -> Scores:
    """Rebuild the exact :class:`Scores` of a status written by :func:`scores_status`."""
    table = dict(values)
    criteria = [key[: -len(SUMS_KEY) - 1] for key, _ in values if key.endswith("/" + SUMS_KEY)]
    if not criteria or "_thresholds" not in table:
        raise InputError(
            "the diagnostic status carries no dispeval sums (is it from a dispeval evaluator?)"
        )
    sums = np.array([[float(v) for v in table[f"{c}/{SUMS_KEY}"].split()] for c in criteria])
    if sums.shape[1] != len(SUM_FIELDS):
        raise InputError(
            f"the diagnostic sums have {sums.shape[1]} fields, expected {len(SUM_FIELDS)}"
        )
    if measures is None:  # every measure some criterion carries (GT and GT-free ones)
        known = set(criteria)
        measures = list(
            dict.fromkeys(
                key.rpartition("/")[2]
                for key, _ in values
                if key.rpartition("/")[0] in known and key.rpartition("/")[2] not in ("n", SUMS_KEY)
            )
        )
    return Scores(
        criteria=tuple(criteria),
        measures=tuple(measures),
        sums=sums,
        thresholds=np.array([float(t) for t in table["_thresholds"].split()]),
        quantiles={
            c: {
                m: float(table[f"{c}/{m}"])
                for m in measures
                if m.startswith("a") and f"{c}/{m}" in table
            }
            for c in criteria
        },
        relative=table.get("_relative") == "1",
        overlapping=tuple(table.get("_overlapping", "").split()),
        policy=table.get("_policy", "interpolate"),
    )


ALWAYS_SCORED = (registry.POINTS.name, *registry.names(needs=registry.NEEDS_NONE))
"""What every criterion's vector starts with (``n``, ``density``): they need nothing."""


def vector_labels(criteria: Sequence[str], measures: Sequence[str]) -> list[str]:
    """The fixed order of a score vector: per criterion ``n``, ``density``, then each measure."""
    labels: list[str] = []
    for criterion in criteria:
        labels.extend(f"{criterion}/{m}" for m in ALWAYS_SCORED)
        labels.extend(
            f"{criterion}/{m}" for m in measures if m not in ALWAYS_SCORED and applies(m, criterion)
        )
    return labels


def score_vector(scores: Scores, labels: Sequence[str]) -> list[float]:
    """The numbers of ``labels`` in order (NaN where undefined)."""
    vector = []
    for label in labels:
        criterion, _, measure = label.rpartition("/")
        vector.append(float(scores[criterion][measure]))
    return vector


def problem_status(
    method: str | None,
    topic: str,
    message: str,
    estimate_stamp: int | None = None,
    arrival: int | None = None,
    unscored: Mapping[str, tuple[int, int]] | None = None,
) -> StatusRecord:
    """The ERROR status of a frame that could not be scored (no scores, so summaries skip it).

    A failed estimate was still delivered: its latency follows the problem, as ``dispeval
    bag`` keeps it: a method's ``arrival`` (and ``estimate_stamp``); on a ground-truth
    problem, ``unscored`` (method → (estimate stamp, arrival)) as ``METHOD/_arrival`` keys.
    """
    values = [(PROBLEM_KEY, message)]
    _timing_values(values, estimate_stamp, arrival)
    for name, (sent, received) in (unscored or {}).items():
        values.append((f"{name}/{ESTIMATE_STAMP_KEY}", str(int(sent))))
        values.append((f"{name}/{ARRIVAL_KEY}", str(int(received))))
    return StatusRecord(
        method if method is not None else GROUND_TRUTH, topic, ERROR, message, tuple(values)
    )


def problem_statuses(
    result: FrameResult, topics: Mapping[str, str], gt_topic: str
) -> list[StatusRecord]:
    """The ERROR statuses of a frame's problems, as every front end publishes them.

    Each estimate delivered but not scored keeps its latency: on its own problem, else on
    the ground truth's.
    """
    failed = {method for method, _ in result.problems if method is not None}
    unscored = {
        method: (result.sent[method], arrival)
        for method, arrival in result.arrivals.items()
        if method not in result.scores and method not in failed and method in result.sent
    }
    records = []
    for method, message in result.problems:
        if method is None:
            records.append(problem_status(None, gt_topic, message, unscored=unscored))
            unscored = {}  # once per frame
        else:
            sent, arrival = result.sent.get(method), result.arrivals.get(method)
            records.append(problem_status(method, topics[method], message, sent, arrival))
    return records


def read_problem(record: StatusRecord) -> tuple[str | None, str] | None:
    """``(method or None for the ground truth, message)`` of a problem status, else None.

    Also reads problem statuses without values (as earlier evaluators sent them).
    """
    if record.level != ERROR or (record.values and record.values[0][0] != PROBLEM_KEY):
        return None
    return (None if record.name == GROUND_TRUTH else record.name, record.message)
