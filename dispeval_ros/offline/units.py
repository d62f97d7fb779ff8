"""Units of work of ``dispeval bag``: time slices of bags, planned by the driver, run anywhere.

A unit is read, joined and scored independently, by whichever executor runs it (in process,
a process pool, a Dask worker), and comes back as rows for the driver to store. Units are cut
by log time, the clock of the join's waits (see :mod:`~dispeval_ros.stream.join`): a unit
reads ``margin`` (tolerance + lateness) of log time beyond its edges, so that messages near an
edge join exactly as in a single pass, and keeps only the ground-truth frames, unmatched
estimates and dropped frames whose deciding message (the GT frame; the estimate, if unmatched)
was logged inside it. Header stamps only pair messages and name the stored frames, so a bag
whose stamps are far from its log time (re-recorded, simulated time) loses nothing.

Each process opens a bag once and keeps it open for the units it runs (opening a rosbag2
folder parses its metadata YAML: 50–100 ms, as long as reading dozens of frames).
"""

from __future__ import annotations

import bisect
import contextlib
import dataclasses
import os
import traceback
from collections import Counter, OrderedDict, deque
from collections.abc import Collection, Generator, Iterable, Iterator
from concurrent.futures import Future
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

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
from dispeval_ros.errors import DispevalError, InputError
from dispeval_ros.io.bags import BagSource, require_topic
from dispeval_ros.io.messages import stamp_ns
from dispeval_ros.io.store import PreparedUnit, failure_record, prepare_unit
from dispeval_ros.offline.memory import keep_frames_on_the_heap
from dispeval_ros.offline.threads import (  # noqa: F401 (executors and tests import them here)
    close_scoring_pools,
    read_ahead,
    scoring_pool,
    scoring_threads,
)
from dispeval_ros.stream.confidence import ConfidencePool
from dispeval_ros.stream.config import TF_STATIC_TOPIC, TF_TOPIC
from dispeval_ros.stream.core import CoreConfig, EvaluationCore, FrameResult
from dispeval_ros.stream.flicker import FlickerScore
from dispeval_ros.stream.join import FrameSet, JoinEvent
from dispeval_ros.stream.pairs import MotionPair

DEFAULT_SLICE_NS = 5_000_000_000
AUTO_SLICE_BOUNDS_NS = (1_000_000_000, 60_000_000_000)
"""``--slice auto`` keeps units between 1 s (overhead) and 60 s (what a kill can cost), and
at least twice the margin a unit reads beyond each edge (so reading costs at most 2×)."""
UNITS_PER_WORKER = 4
"""``--slice auto`` cuts a bag into about this many units per worker (load balance)."""
OPEN_BAGS_PER_PROCESS = 16
FRAMES_IN_FLIGHT_PER_THREAD = 2
"""Frames handed to each scoring thread ahead of the oldest one collected (none waits idle)."""
DENSE_SLICES = 10_000
"""Bags of up to this many slices (or twice their messages) are cut without a pass over them."""
_FIRST, _LAST = -(2**62), 2**62


@dataclass(frozen=True)
class Unit:
    """One time slice ``[start_ns, stop_ns)`` of one bag (log time, in nanoseconds)."""

    path: Path
    sequence: str
    name: str
    start_ns: int
    stop_ns: int
    margin_ns: int
    seen_stamps: frozenset[int] = frozenset()
    """GT stamps that units before this one kept: a copy of such a frame here is a repeat (a
    bag holding a frame again, further back than this unit reads), ignored as in one pass."""


@dataclass
class UnitResult:
    """What one unit produced, ready to be written in one transaction."""

    unit: Unit
    frames: list[FrameScores] = field(default_factory=list)
    problems: list[Problem] = field(default_factory=list)
    counts: dict[str, MatchCounts] = field(default_factory=dict)
    timing: list[FrameTiming] = field(default_factory=list)
    """When each method's estimate of a kept frame was logged (scored or not)."""
    pairs: list[FramePair] = field(default_factory=list)
    """With ``temporal``: the pairs whose later frame this unit kept."""
    motion: list[FrameMotion] = field(default_factory=list)
    """With ``egomotion``: the ego-motion residuals of those pairs."""
    flicker: list[FrameFlicker] = field(default_factory=list)
    """With ``flicker``: the windows of the frames this unit kept (never spanning units)."""
    confidence: list[PooledConfidence] = field(default_factory=list)
    """With ``confidences``: per method, its confidence sums over the frames this unit kept."""
    messages: int = 0
    kept: dict[int, int] = field(default_factory=dict)
    """Stamp → arrival of the GT frames this unit kept (scored or dropped)."""
    seen: list[tuple[int, int]] = field(default_factory=list)
    """(stamp, arrival) of every GT message its join took as a frame (not as a repeat)."""


@dataclass(frozen=True)
class UnitRows:
    """A unit's database rows (made where it ran) and what the progress display counts."""

    unit: Unit
    rows: PreparedUnit
    frames: int
    problems: int
    messages: int
    kept: tuple[tuple[int, int], ...] = ()
    """(stamp, arrival) of the GT frames the unit kept."""
    seen: tuple[tuple[int, int], ...] = ()
    """(stamp, arrival) of the GT messages it took as frames: the driver checks that no earlier
    unit kept an earlier copy of one (see :func:`repeated_elsewhere`)."""

    @classmethod
    def of(cls, result: UnitResult) -> UnitRows:
        """The rows of an evaluated unit."""
        unit = result.unit
        rows = prepare_unit(
            unit.sequence,
            unit.name,
            result.frames,
            result.problems,
            result.counts,
            result.timing,
            result.pairs,
            result.motion,
            result.flicker,
            result.confidence,
        )
        return cls(
            unit,
            rows,
            len(result.frames),
            len(result.problems),
            result.messages,
            tuple(result.kept.items()),
            tuple(result.seen),
        )


@dataclass(frozen=True)
class UnitFailure:
    """A unit that raised (a bug, memory) or whose worker died: the driver retries it."""

    unit: Unit
    message: str


@dataclass(frozen=True)
class BagPlan:
    """A bag's units, what the results database records about it, and what to warn of."""

    units: list[Unit]
    info: dict[str, object]
    warning: str | None = None


# -- opening bags once per process ----------------------------------------------------------

_open_bags: OrderedDict[tuple[str, int, int], BagSource] = OrderedDict()


def open_bag(path: Path) -> BagSource:
    """The bag at ``path``, opened once per process (reopened when the file changes)."""
    try:
        stat = os.stat(path)
        key = (str(path), stat.st_mtime_ns, stat.st_size)
    except OSError:
        return BagSource(path)  # raises the bag reader's one-line error
    source = _open_bags.get(key)
    if source is not None:
        _open_bags.move_to_end(key)
        return source
    source = BagSource(path)
    _open_bags[key] = source
    while len(_open_bags) > OPEN_BAGS_PER_PROCESS:
        _open_bags.popitem(last=False)[1].close()
    return source


def forget_bags() -> None:
    """Drop the bags a forked child inherited (their file positions are the parent's)."""
    _open_bags.clear()


def close_bags() -> None:
    """Close every bag this process keeps open."""
    while _open_bags:
        _open_bags.popitem()[1].close()


# -- planning -------------------------------------------------------------------------------


def auto_slice_ns(start_ns: int, end_ns: int, workers: int, margin_ns: int = 0) -> int:
    """A slice length for a bag: about :data:`UNITS_PER_WORKER` units per worker, in bounds.

    ``end_ns - start_ns``: the log time the bag's messages occupy (see
    :func:`occupied_ns`), not its span when its clock jumped.
    """
    low, high = AUTO_SLICE_BOUNDS_NS
    low = max(low, 2 * margin_ns)
    wanted = (end_ns - start_ns) // max(1, UNITS_PER_WORKER * workers)
    return int(min(high, max(low, wanted)) // 100_000_000 * 100_000_000)


def auto_slice_for(source: BagSource, workers: int, margin_ns: int = 0) -> int:
    """``--slice auto`` for a bag, from the log time its messages occupy."""
    grain = max(AUTO_SLICE_BOUNDS_NS[0], 2 * margin_ns)
    return auto_slice_ns(0, occupied_ns(source, grain), workers, margin_ns)


def occupied_slices(source: BagSource, slice_ns: int) -> list[int]:
    """The indexes ``k`` of the slices ``[start + k·slice, start + (k+1)·slice)`` to plan.

    Every slice up to the end when there are no more of them than :func:`dense_limit` (no
    pass over the bag); else those the bag's log times fall in (one pass that decodes
    nothing), so a bag whose clock jumped (1970, then 2023) has as many as its messages fill,
    not one per slice of the 53 years between.
    """
    slices = (source.end_ns - source.start_ns) // slice_ns + 1
    if slices <= dense_limit(source):
        return list(range(slices))
    return _filled_slices(source, slice_ns)


def _filled_slices(source: BagSource, slice_ns: int) -> list[int]:
    """The slices a message's log time falls in (at least the first)."""
    start = source.start_ns
    found: set[int] = set()
    with contextlib.suppress(DispevalError):  # damaged storage: the units report it
        found.update(max(0, (log_ns - start) // slice_ns) for log_ns in source.log_times())
    return sorted(found) or [0]


def dense_limit(source: BagSource) -> int:
    """Up to this many slices, every slice of the span is a unit (bounded by the messages)."""
    return max(2 * source.message_count, DENSE_SLICES)


def occupied_ns(source: BagSource, grain_ns: int) -> int:
    """The log time a bag's messages occupy, to ``grain_ns``: its span unless its clock jumped."""
    span = source.end_ns - source.start_ns
    if span // grain_ns + 1 <= dense_limit(source):
        return span
    return len(_filled_slices(source, grain_ns)) * grain_ns


def check_topics(source: BagSource, config: CoreConfig) -> None:
    """Every configured topic exists with the expected type (else one error listing the bag's topics)."""
    for topic, msgtype in config.topics.items():
        if config.egomotion and topic == TF_STATIC_TOPIC and topic not in source.topics:
            continue  # the camera frame may be on /tf itself
        if config.egomotion and topic == TF_TOPIC and topic not in source.topics:
            raise InputError(
                f"{source.path} has no {topic} to take the camera's motion from (--egomotion): "
                "record the odometry's transforms (odom → base_link) with the streams"
            )
        if topic == config.tf_topic and topic not in source.topics:
            raise InputError(
                f"{source.path} has no {topic} to take the LiDAR → camera transform from; "
                "give it with --extrinsic FILE (a 4×4 matrix or 'x y z qx qy qz qw')"
            )
        require_topic(source, topic, [msgtype])


def push_static_transforms(source: BagSource, core: EvaluationCore) -> None:
    """Give ``core`` every /tf_static message of the bag (point-cloud GT without --extrinsic).

    Static transforms are latched: recorded once, near the start, so a slice of the bag read
    on its own would miss them.
    """
    topic = core.config.tf_topic or (TF_STATIC_TOPIC if core.config.egomotion else None)
    if topic and topic in source.topics:
        for _, _, msg in source.messages([topic]):
            core.push(topic, msg)


def stamp_offset_ns(source: BagSource, topic: str) -> int | None:
    """Log time minus header stamp of the first message on ``topic`` (None: none readable).

    Cheap: one message, not a pass over the bag.
    """
    messages = source.messages([topic])
    try:
        first = next(messages, None)
    except DispevalError:  # an unreadable message is the units' problem row, not the plan's
        first = None
    finally:
        if isinstance(messages, Generator):
            messages.close()
    return None if first is None else log_minus_stamp(first[1], first[2])


def log_minus_stamp(log_ns: int, msg: Any) -> int | None:
    """How far a message was logged after its header stamp, in ns (None: it has no header)."""
    return log_ns - stamp_ns(msg.header) if hasattr(msg, "header") else None


def duration_text(ns: int) -> str:
    """A duration a reader takes in at once: "6.2 years (1.96e+08 s)", "350 ms"."""
    seconds = abs(ns) / 1e9
    for unit, size in (("years", 365.25 * 86400), ("days", 86400.0), ("hours", 3600.0)):
        if seconds >= size:
            return f"{seconds / size:.1f} {unit} ({seconds:.3g} s)"
    return f"{seconds:.3g} s" if seconds >= 1 else f"{seconds * 1e3:.3g} ms"


def stamp_offset_warning(path: Path, offset_ns: int | None, slice_ns: int) -> str | None:
    """What to tell when a bag's header stamps are more than a slice from its log time."""
    if offset_ns is None or abs(offset_ns) <= slice_ns:
        return None
    side = "before" if offset_ns > 0 else "after"
    return (
        f"{path}: header stamps are {duration_text(offset_ns)} {side} the log time (more than "
        f"a slice, {duration_text(slice_ns)}); units and waits follow the log time, frames are "
        "joined and stored by their stamps"
    )


def plan_bag(path: Path, sequence: str, config: CoreConfig, slice_ns: int) -> BagPlan:
    """Check the bag's topics and cut its log time into units where its messages are.

    Each occupied slice of ``slice_ns`` (:func:`occupied_slices`) starts a unit, named by
    its index, that runs to the next one: the units cover all time, so every message (and
    frame) is in exactly one, and an empty stretch adds none. The plan depends only on the
    bag and the slice length, so a resumed run (with any executor) finds the same units.
    The info records how far the first ground-truth frame's stamp is from its log time
    (``stamp_offset_ns``: log time minus stamp).
    """
    source = open_bag(path)
    check_topics(source, config)
    start = source.start_ns
    margin = config.tolerance_ns + config.lateness_ns
    slices = occupied_slices(source, slice_ns)
    edges = [_FIRST, *(start + k * slice_ns for k in slices[1:]), _LAST]
    units = [
        Unit(path, sequence, f"{k:06d}", low, high, margin)
        for k, low, high in zip(slices, edges[:-1], edges[1:], strict=True)
    ]
    info: dict[str, object] = {
        "format": source.format,
        "start_ns": source.start_ns,
        "end_ns": source.end_ns,
        "messages": source.message_count,
    }
    offset = stamp_offset_ns(source, config.gt_topic)
    if offset is not None:
        info["stamp_offset_ns"] = offset
    warning = stamp_offset_warning(path, offset, slice_ns)
    if warning is not None:
        info["warning"] = warning
    return BagPlan(units, info, warning)


# -- running --------------------------------------------------------------------------------


def evaluate_unit(config: CoreConfig, unit: Unit, threads: int = 1) -> UnitResult:
    """Read, join and score one slice; per-frame problems are recorded, never raised.

    The bag is read ahead on a thread while frames are scored on ``threads`` threads (see
    :func:`scoring_pool`): whole frames side by side (partition and every method of a frame
    in one thread), or, where a frame may need transforms read later from the stream, each
    frame's methods side by side. The rows are the same as in one thread, in stream order.
    """
    result = UnitResult(unit)
    pool = scoring_pool(threads)
    frame_pool = pool if config.tf_topic is None else None  # whole frames side by side
    core = EvaluationCore(
        config,
        keep_events=True,
        executor=pool if frame_pool is None else None,
        repeat_memory_ns=None,  # a unit is short: every GT stamp it saw is remembered
        seen_stamps=unit.seen_stamps,
        wait_for_motion=True,
    )
    inside = range(unit.start_ns, unit.stop_ns)  # of log time: the arrival clock
    matched: Counter[str] = Counter()
    failed: Counter[str] = Counter()
    scoring: deque[tuple[FrameSet[Any, Any], Future[FrameResult], bool]] = deque()
    before: list[FrameSet[Any, Any]] = []  # the last frame not kept, for the pair it begins
    confidence = ConfidencePool(unit.sequence, config.confidence_presets)

    def collect(frame_set: FrameSet[Any, Any], frame: FrameResult, keep: bool = True) -> None:
        core.pair(frame)  # in the join's order, kept or not (see stream/pairs.py)
        result.motion.extend(motion_records(unit.sequence, frame.motion_pairs, result.kept))
        if not keep:
            return
        core.window(frame)  # windows of the kept frames only: they never span units
        result.flicker.extend(flicker_records(unit.sequence, frame.flicker))
        if frame.pair_previous is not None:
            previous = frame.pair_previous
            result.pairs.extend(
                FramePair(unit.sequence, frame.stamp, method, previous, scores)
                for method, scores in frame.pairs.items()
            )
        result.timing.extend(
            FrameTiming(unit.sequence, frame.stamp, method, frame.sent[method], arrival)
            for method, arrival in frame.arrivals.items()
        )
        confidence.add(frame)
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

    def collect_oldest() -> None:
        frame_set, future, keep = scoring.popleft()
        collect(frame_set, future.result(), keep)

    def score(frame_set: FrameSet[Any, Any], keep: bool) -> None:
        if frame_pool is None:
            collect(frame_set, core.score(frame_set), keep)
            return
        scoring.append((frame_set, frame_pool.submit(core.scorer(frame_set)), keep))
        while len(scoring) > FRAMES_IN_FLIGHT_PER_THREAD * threads:
            collect_oldest()

    def handle(frame_sets: list[FrameSet[Any, Any]]) -> None:
        for frame_set in frame_sets:
            if frame_set.arrival not in inside:
                before[:] = [frame_set] if core.pairs is not None else []
                continue
            if before:  # the earlier frame of the pair this kept frame ends (not stored)
                score(before.pop(), False)
            result.kept[frame_set.stamp] = frame_set.arrival
            score(frame_set, True)

    lookback = config.pair_gap_ns if core.pairs is not None else 0  # the frame before
    read_from = None if unit.start_ns <= _FIRST else unit.start_ns - unit.margin_ns - lookback
    read_to = None if unit.stop_ns >= _LAST else unit.stop_ns + unit.margin_ns

    def messages(source: BagSource) -> Iterator[tuple[str, int, Any]]:
        """The unit's messages, after the GT of one margin more before them.

        A frame logged again within a margin of its first copy is then a repeat here too, as
        in one pass (further apart, the driver tells: :attr:`Unit.seen_stamps`).
        """
        if read_from is not None:
            yield from source.messages([config.gt_topic], read_from - unit.margin_ns, read_from)
        topics = [t for t in config.topics if t in source.topics]  # (/tf_static: optional)
        yield from source.messages(topics, read_from, read_to)

    try:
        source = open_bag(unit.path)
        push_static_transforms(source, core)
        with contextlib.closing(read_ahead(messages(source))) as ahead:  # stopped before the next
            for topic, log_ns, msg in ahead:
                result.messages += 1
                handle(core.push(topic, msg, log_ns))
    except DispevalError as error:
        result.problems.append(Problem(unit.sequence, None, None, f"reading stopped: {error}"))
    handle(core.flush())
    while scoring:
        collect_oldest()
    tail = core.finish_pairs()  # ego-motion pairs that waited for /tf to the end
    if tail is not None:
        result.motion.extend(motion_records(unit.sequence, tail.motion, result.kept))
        result.problems.extend(Problem(unit.sequence, None, m, text) for m, text in tail.problems)
    windows = core.finish_windows()  # the unit's last windows, partial ones too
    if windows is not None:
        result.flicker.extend(flicker_records(unit.sequence, windows.windows))
        result.problems.extend(Problem(unit.sequence, None, m, t) for m, t in windows.problems)
    result.confidence = confidence.records()
    kept = [event for event in core.joiner.events or [] if event.arrival in inside]
    events = Counter((event.kind, event.method) for event in kept)
    result.kept.update((e.stamp, e.arrival) for e in kept if e.kind == "dropped")
    result.seen = [(e.stamp, e.arrival) for e in core.joiner.events or [] if e.kind == "frame"]
    result.problems.extend(
        Problem(
            unit.sequence,
            stamp,
            None,
            f"{config.gt_topic} holds the frame at {stamp} more than once: the first is scored, "
            "the others are ignored",
        )
        for kind, _, stamp, *_ in kept
        if kind == "repeated"
    )
    result.problems.extend(unmatched_hints(config, unit.sequence, kept, core.joiner.events or []))
    if core.motion is not None:  # /tf samples refused (said per unit, with their count)
        result.problems.extend(
            Problem(unit.sequence, None, None, text) for text in core.motion.problems()
        )
    for method in config.methods:
        result.counts[method] = MatchCounts(
            matched=matched[method],
            unmatched=events["unmatched", method],
            dropped=events["dropped", method],
            failed=failed[method],
        )
    return result


def motion_records(
    sequence: str, pairs: Iterable[MotionPair], kept: Collection[int]
) -> list[FrameMotion]:
    """The ego-motion pairs (and their drift) whose later frame a unit keeps, to store."""
    return [FrameMotion(sequence, p.stamp, p.method, p.previous, p.sums, p.drift) for p in pairs
            if p.stamp in kept]  # fmt: skip


def flicker_records(sequence: str, windows: Iterable[FlickerScore]) -> list[FrameFlicker]:
    """A unit's flicker windows as records to store."""
    return [FrameFlicker(sequence, w.start, w.stamp, w.method, w.frames, w.sums) for w in windows]


def unmatched_hints(
    config: CoreConfig, sequence: str, kept: Iterable[JoinEvent], read: Iterable[JoinEvent]
) -> list[Problem]:
    """One problem per method whose ``kept`` estimates had no GT stamp within the tolerance.

    ``read``: every event of the unit's read (its GT "frame" events give the stamps). A user
    sees at once whether the tolerance is too tight (a LiDAR stamped 10.5 ms from its images)
    or the streams do not belong together.
    """
    frames = sorted(event.stamp for event in read if event.kind == "frame")
    if not frames:
        return []
    gaps: dict[str, list[int]] = {}
    for event in kept:
        if event.kind == "unmatched":
            index = bisect.bisect_left(frames, event.stamp)
            gap = min(
                abs(frames[i] - event.stamp) for i in (index - 1, index) if 0 <= i < len(frames)
            )
            if gap > config.tolerance_ns:  # (within it, a frame was there: late or a copy)
                gaps.setdefault(event.method, []).append(gap)
    return [
        Problem(
            sequence,
            None,
            method,
            f"{len(found)} estimate(s) of {method} found no {config.gt_topic} frame within "
            f"--tolerance {config.tolerance_ns / 1e6:g} ms; the nearest GT stamps were "
            f"{min(found) / 1e6:.3f}–{max(found) / 1e6:.3f} ms away",
        )
        for method, found in gaps.items()
    ]


def repeated_elsewhere(rows: UnitRows, first: dict[int, int], stored: set[int]) -> frozenset[int]:
    """GT stamps ``rows`` took as frames though units before it kept an earlier copy.

    ``first``: stamp → arrival of the frames kept by the units before (this run); ``stored``:
    stamps stored by an earlier run (arrival unknown: only a frame kept again counts). A unit
    reads a margin beyond its edges, so a frame logged again further back than that looks new
    to it: run again with these as :attr:`Unit.seen_stamps`, it joins as one pass does.
    """
    again = {stamp for stamp, arrival in rows.seen if first.get(stamp, arrival) < arrival}
    again |= stored & {stamp for stamp, _ in rows.kept}
    return frozenset(again)


def run_unit(config: CoreConfig, unit: Unit, threads: int = 1) -> UnitRows | UnitFailure:
    """The rows of :func:`evaluate_unit`; anything unexpected is a failure to retry."""
    keep_frames_on_the_heap()
    try:
        return UnitRows.of(evaluate_unit(config, unit, threads))
    except Exception as error:  # a bug or exhaustion: the driver retries, then records it
        where = traceback.extract_tb(error.__traceback__)[-1]
        text = " ".join(str(error).split()) or type(error).__name__
        return UnitFailure(
            unit,
            f"{type(error).__name__}: {text} ({Path(where.filename).name}:{where.lineno})",
        )


def failed_result(failure: UnitFailure, attempts: int) -> UnitRows:
    """What is stored for a unit that failed every attempt: one problem, no frames.

    It is stored as the unit's failure record (:func:`failure_record`), so ``--resume``
    tries the unit again.
    """
    unit = failure.unit
    return UnitRows.of(
        UnitResult(
            dataclasses.replace(unit, name=failure_record(unit.name)),
            problems=[
                Problem(
                    unit.sequence,
                    None,
                    None,
                    f"unit {unit.name} failed {attempts} times, not evaluated: {failure.message}",
                )
            ],
        )
    )
