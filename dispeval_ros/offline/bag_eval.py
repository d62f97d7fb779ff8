"""Evaluate recorded bags: each bag is a sequence, cut into time slices (units of work).

A unit is read, joined and scored independently (so ``--jobs N`` runs N of them at once,
each process with its own reader) and written to the results database in one transaction
with its match counts, so a killed run loses at most the units in flight and ``--resume``
continues without duplicating anything. A unit reads ``margin`` beyond its edges so that
frames near an edge join exactly as in a single pass; it keeps only the ground-truth frames,
unmatched estimates and dropped frames whose stamps fall inside it.
"""

from __future__ import annotations

import multiprocessing
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dispeval_ros.errors import DispevalError, InputError
from dispeval_ros.io.bags import BagSource, require_topic
from dispeval_ros.io.store import FrameScores, MatchCounts, Problem, ResultsStore
from dispeval_ros.live.core import CoreConfig, EvaluationCore
from dispeval_ros.live.join import FrameSet

DEFAULT_SLICE_NS = 5_000_000_000


@dataclass(frozen=True)
class Unit:
    """One time slice ``[start_ns, stop_ns)`` of one bag (stamps, in nanoseconds)."""

    path: Path
    sequence: str
    name: str
    start_ns: int
    stop_ns: int
    margin_ns: int


@dataclass
class UnitResult:
    """What one unit produced, ready to be written in one transaction."""

    unit: Unit
    frames: list[FrameScores] = field(default_factory=list)
    problems: list[Problem] = field(default_factory=list)
    counts: dict[str, MatchCounts] = field(default_factory=dict)
    messages: int = 0


def sequence_names(bags: Sequence[Path]) -> list[str]:
    """Unique, readable sequence names from bag paths (the stem, suffixed when repeated)."""
    stems = [(path.stem if path.suffix else path.name) or "bag" for path in bags]
    seen: Counter[str] = Counter()
    names = []
    for stem in stems:
        seen[stem] += 1
        names.append(stem if stems.count(stem) == 1 else f"{stem}-{seen[stem]}")
    return names


def check_topics(source: BagSource, config: CoreConfig) -> None:
    """Every configured topic exists with the expected type (else one error listing the bag's topics)."""
    for topic, msgtype in config.topics.items():
        if topic == config.tf_topic and topic not in source.topics:
            raise InputError(
                f"{source.path} has no {topic} to take the LiDAR → camera transform from; "
                "give it with --extrinsic FILE (a 4×4 matrix or 'x y z qx qy qz qw')"
            )
        require_topic(source, topic, [msgtype])


def plan_units(path: Path, sequence: str, config: CoreConfig, slice_ns: int) -> list[Unit]:
    """Cut a bag's time span into slices; the plan depends only on the bag and the slice length."""
    with BagSource(path) as source:
        check_topics(source, config)
        start, end = source.start_ns, source.end_ns
    margin = config.tolerance_ns + config.lateness_ns
    units = []
    edge = start - margin  # header stamps may precede the first log time
    index = 0
    while edge <= end + margin:
        stop = edge + slice_ns
        units.append(Unit(path, sequence, f"{index:06d}", edge, stop, margin))
        edge = stop
        index += 1
    units[0] = Unit(path, sequence, units[0].name, -(2**62), units[0].stop_ns, margin)
    last = units[-1]
    units[-1] = Unit(path, sequence, last.name, last.start_ns, 2**62, margin)
    return units


def push_static_transforms(source: BagSource, core: EvaluationCore) -> None:
    """Give ``core`` every /tf_static message of the bag (point-cloud GT without --extrinsic).

    Static transforms are latched: recorded once, near the start, so a slice of the bag read
    on its own would miss them.
    """
    topic = core.config.tf_topic
    if topic:
        for _, _, msg in source.messages([topic]):
            core.push(topic, msg)


def evaluate_unit(config: CoreConfig, unit: Unit) -> UnitResult:
    """Read, join and score one slice; per-frame problems are recorded, never raised."""
    result = UnitResult(unit)
    core = EvaluationCore(config, keep_events=True)
    inside = range(unit.start_ns, unit.stop_ns)
    matched: Counter[str] = Counter()
    failed: Counter[str] = Counter()

    def handle(frame_sets: list[FrameSet[Any, Any]]) -> None:
        for frame_set in frame_sets:
            if frame_set.stamp not in inside:
                continue
            frame = core.score(frame_set)
            for method, scores in frame.scores.items():
                result.frames.append(FrameScores(unit.sequence, frame.stamp, method, scores))
                matched[method] += 1
            for method in frame_set.estimates:
                if method not in frame.scores:
                    failed[method] += 1
            result.problems.extend(
                Problem(unit.sequence, frame.stamp, method, message)
                for method, message in frame.problems
            )

    read_from = None if unit.start_ns < -(2**61) else unit.start_ns - unit.margin_ns
    read_to = None if unit.stop_ns > 2**61 else unit.stop_ns + unit.margin_ns
    try:
        with BagSource(unit.path) as source:
            push_static_transforms(source, core)
            for topic, _, msg in source.messages(list(config.topics), read_from, read_to):
                result.messages += 1
                handle(core.push(topic, msg))
    except DispevalError as error:
        result.problems.append(Problem(unit.sequence, None, None, f"reading stopped: {error}"))
    handle(core.flush())
    events = Counter(
        (kind, method) for kind, method, stamp in core.joiner.events or [] if stamp in inside
    )
    for method in config.methods:
        result.counts[method] = MatchCounts(
            matched=matched[method],
            unmatched=events["unmatched", method],
            dropped=events["dropped", method],
            failed=failed[method],
        )
    return result


def _evaluate(args: tuple[CoreConfig, Unit]) -> UnitResult:
    return evaluate_unit(*args)


@dataclass
class RunReport:
    """What a run did: units written now and before (resume), frames, problems."""

    units_done: int = 0
    units_skipped: int = 0
    frames: int = 0
    problems: int = 0
    messages: int = 0


def evaluate_bags(
    bags: Sequence[Path],
    config: CoreConfig,
    store: ResultsStore,
    *,
    jobs: int = 1,
    slice_ns: int = DEFAULT_SLICE_NS,
    progress: Callable[[int, int, RunReport], None] | None = None,
) -> RunReport:
    """Evaluate every bag into ``store`` (units already done there are skipped)."""
    if jobs < 1:
        raise InputError(f"--jobs must be at least 1, got {jobs}")
    units: list[Unit] = []
    for path, sequence in zip(bags, sequence_names(bags), strict=True):
        planned = plan_units(path, sequence, config, slice_ns)
        with BagSource(path) as source:
            store.set_sequence(
                sequence,
                str(path),
                {
                    "format": source.format,
                    "start_ns": source.start_ns,
                    "end_ns": source.end_ns,
                    "messages": source.message_count,
                },
            )
        done = store.done_units(sequence)
        units.extend(unit for unit in planned if unit.name not in done)
    report = RunReport(units_skipped=0)
    total = len(units)
    for result in _run_units(config, units, jobs):
        store.add_unit(
            result.unit.sequence, result.unit.name, result.frames, result.problems, result.counts
        )
        report.units_done += 1
        report.frames += len(result.frames)
        report.problems += len(result.problems)
        report.messages += result.messages
        if progress is not None:
            progress(report.units_done, total, report)
    return report


def _run_units(config: CoreConfig, units: list[Unit], jobs: int) -> Iterator[UnitResult]:
    """Results in plan order: in this process, or from ``jobs`` worker processes."""
    if jobs == 1 or len(units) <= 1:
        for unit in units:
            yield evaluate_unit(config, unit)
        return
    context = multiprocessing.get_context("spawn" if _threads_started() else "fork")
    with context.Pool(jobs) as pool:
        yield from pool.imap(_evaluate, [(config, unit) for unit in units])


def _threads_started() -> bool:
    import threading

    return threading.active_count() > 1
