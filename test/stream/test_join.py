"""The stamp joiner: exact pairs, nearest within tolerance, drops and unmatched counts."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from dispeval_ros.errors import ConfigurationError
from dispeval_ros.stream.join import StampJoiner

MS = 1_000_000


def run(joiner: StampJoiner, events: list[tuple[str, int]]) -> dict[int, dict[str, int]]:
    """Feed (source, stamp) events; returns GT stamp → {method: estimate stamp}."""
    joined = {}
    for source, stamp in events:
        out = (
            joiner.add_gt(stamp, f"gt{stamp}")
            if source == "gt"
            else joiner.add_estimate(source, stamp, source)
        )
        for frame_set in out:
            joined[frame_set.stamp] = {m: s for m, (s, _) in frame_set.estimates.items()}
    for frame_set in joiner.flush():
        joined[frame_set.stamp] = {m: s for m, (s, _) in frame_set.estimates.items()}
    return joined


def test_exact_stamps_pair_immediately() -> None:
    joiner = StampJoiner(["a", "b"], tolerance=5 * MS)
    assert joiner.add_gt(100 * MS, "g") == []
    assert joiner.add_estimate("a", 100 * MS, "ea") == []
    done = joiner.add_estimate("b", 100 * MS, "eb")
    assert len(done) == 1
    assert done[0].gt == "g"
    assert done[0].estimates == {"a": (100 * MS, "ea"), "b": (100 * MS, "eb")}
    assert joiner.counts["a"].matched == 1
    assert joiner.buffered == 0


def test_estimate_before_gt_pairs_on_exact_stamp() -> None:
    joiner = StampJoiner(["a"], tolerance=0)
    assert joiner.add_estimate("a", 7, "e") == []
    done = joiner.add_gt(7, "g")
    assert [f.estimates for f in done] == [{"a": (7, "e")}]


def test_nearest_within_tolerance_and_unmatched() -> None:
    joiner = StampJoiner(["a"], tolerance=3 * MS, lateness=150 * MS)
    joined = run(
        joiner,
        [
            ("gt", 0),
            ("gt", 100 * MS),
            ("a", 2 * MS),
            ("a", 50 * MS),
            ("a", 99 * MS),
            ("gt", 200 * MS),
        ],
    )
    assert joined == {0: {"a": 2 * MS}, 100 * MS: {"a": 99 * MS}}
    counts = joiner.counts["a"]
    assert (counts.matched, counts.unmatched, counts.dropped) == (
        2,
        1,
        1,
    )  # 50 ms: no GT; 200 ms: no estimate


def test_each_gt_frame_takes_one_estimate_per_method() -> None:
    joiner = StampJoiner(["a"], tolerance=10 * MS)
    joined = run(joiner, [("gt", 100 * MS), ("a", 98 * MS), ("a", 103 * MS)])
    assert joined == {100 * MS: {"a": 98 * MS}}
    assert joiner.counts["a"].unmatched == 1


def test_dropped_frames_are_counted_per_method() -> None:
    joiner = StampJoiner(["a", "b"], tolerance=1 * MS)
    events = []
    for i in range(10):
        events.append(("gt", i * 100 * MS))
        events.append(("a", i * 100 * MS))
        if i not in (3, 7):
            events.append(("b", i * 100 * MS + MS // 2))
    joined = run(joiner, events)
    assert len(joined) == 10
    assert joiner.counts["a"].dropped == 0
    assert joiner.counts["b"].dropped == 2
    assert joiner.counts["b"].matched == 8
    assert all("b" not in joined[i * 100 * MS] for i in (3, 7))


def test_too_late_estimates_are_unmatched() -> None:
    """An estimate arriving later than ``lateness`` finds its GT frame already retired."""
    joiner = StampJoiner(["a"], tolerance=1 * MS, lateness=50 * MS)
    joined = run(joiner, [("gt", 0), ("gt", 100 * MS), ("a", 0), ("a", 100 * MS)])
    assert joined == {100 * MS: {"a": 100 * MS}}
    assert (joiner.counts["a"].unmatched, joiner.counts["a"].dropped) == (1, 1)


def test_late_estimates_within_lateness_still_pair() -> None:
    joiner = StampJoiner(["a"], tolerance=1 * MS, lateness=500 * MS)
    events = [("gt", i * 100 * MS) for i in range(5)] + [("a", i * 100 * MS) for i in range(5)]
    joined = run(joiner, events)
    assert all(joined[i * 100 * MS] == {"a": i * 100 * MS} for i in range(5))


def test_drop_oldest_bounds_memory_and_counts() -> None:
    joiner = StampJoiner(["a"], tolerance=0, lateness=10**12, keep_events=True)
    for i in range(5):
        joiner.add_gt(i, "g")
    dropped = joiner.drop_oldest()
    assert dropped is not None
    assert dropped.stamp == 0
    assert joiner.counts["a"].dropped == 1
    assert [e for e in joiner.events or [] if e.kind != "frame"] == [("dropped", "a", 0, 0)]


def test_configuration_errors() -> None:
    with pytest.raises(ConfigurationError):
        StampJoiner([], tolerance=0)
    with pytest.raises(ConfigurationError):
        StampJoiner(["a"], tolerance=-1)
    with pytest.raises(ConfigurationError, match="unknown method"):
        StampJoiner(["a"], tolerance=0).add_estimate("b", 0, None)


def brute_force(
    gt: list[int], estimates: dict[str, list[int]], tolerance: int
) -> dict[int, dict[str, int]]:
    """Offline reference: per method, in estimate order, exact matches first, then nearest free GT."""
    joined: dict[int, dict[str, int]] = {g: {} for g in gt}
    for method, stamps in estimates.items():
        free = set(gt)
        pending = []
        for stamp in stamps:
            if stamp in free:
                joined[stamp][method] = stamp
                free.discard(stamp)
            else:
                pending.append(stamp)
        for stamp in sorted(pending):
            candidates = [g for g in sorted(free) if abs(g - stamp) <= tolerance]
            if candidates:
                best = min(candidates, key=lambda g: (abs(g - stamp), g))
                joined[best][method] = stamp
                free.discard(best)
    return {g: m for g, m in joined.items() if m}


@settings(max_examples=150, deadline=None)
@given(
    n=st.integers(1, 25),
    drops=st.lists(st.integers(0, 24), max_size=6),
    jitter=st.lists(st.integers(-3, 3), min_size=25, max_size=25),
)
def test_streaming_join_equals_offline_join(n: int, drops: list[int], jitter: list[int]) -> None:
    """With in-order streams, the streaming join pairs exactly like an offline nearest-stamp join."""
    period, tolerance = 100, 4
    gt = [i * period for i in range(n)]
    estimates = {
        "exact": [i * period for i in range(n) if i not in drops],
        "jittered": [i * period + jitter[i] for i in range(n) if i + 1 not in drops],
    }
    events = []
    for i in range(n):
        events.append(("gt", gt[i]))
        for method, stamps in estimates.items():
            events.extend((method, s) for s in stamps if i * period - 50 <= s < i * period + 50)
    joiner = StampJoiner(list(estimates), tolerance=tolerance, lateness=period)
    assert run(joiner, events) == brute_force(gt, estimates, tolerance)
    for method, stamps in estimates.items():
        counts = joiner.counts[method]
        assert counts.matched + counts.unmatched == len(stamps)
        assert counts.matched + counts.dropped == n


def test_a_repeated_ground_truth_stamp_is_ignored_after_its_frame_was_emitted() -> None:
    """A bag holding a frame twice: the first stands, counts stay right, nothing scored twice."""
    joiner: StampJoiner[str, str] = StampJoiner(["a"], tolerance=5, lateness=10, keep_events=True)
    emitted = []
    emitted += joiner.add_gt(100, "gt")
    emitted += joiner.add_estimate("a", 100, "est")  # complete: emitted at once
    emitted += joiner.add_gt(100, "gt again")  # the same frame again
    emitted += joiner.add_estimate("a", 100, "est again")
    emitted += joiner.add_gt(200, "next")
    emitted += joiner.add_estimate("a", 200, "est")
    emitted += joiner.flush()
    assert [(f.stamp, f.gt) for f in emitted] == [(100, "gt"), (200, "next")]
    assert joiner.repeated_gt == 1
    assert ("repeated", "", 100, 100) in (joiner.events or [])
    counts = joiner.counts["a"]
    assert (counts.matched, counts.unmatched, counts.dropped) == (2, 1, 0)


# -- arrival time: waits, and slices of a stream ------------------------------------------------


def test_waits_follow_the_arrival_clock_not_the_stamps() -> None:
    """Stamps years away from the arrival clock: pairing by stamp, waiting by arrival."""
    years = 5 * 365 * 86_400 * 10**9
    joiner: StampJoiner[str, str] = StampJoiner(["a"], tolerance=2 * MS, lateness=100 * MS)
    done = joiner.add_gt(0, "g0", arrival=years)
    done += joiner.add_estimate("a", 1 * MS, "e0", arrival=years + 90 * MS)  # within 102 ms
    done += joiner.add_gt(1000 * MS, "g1", arrival=years + 100 * MS)
    done += joiner.add_estimate("a", 1000 * MS, "e1", arrival=years + 203 * MS)  # 103 ms: late
    done += joiner.flush()
    assert [(f.stamp, f.arrival, f.estimates) for f in done] == [(0, years, {"a": (MS, "e0")})]
    counts = joiner.counts["a"]
    assert (counts.matched, counts.unmatched, counts.dropped) == (1, 1, 1)


def test_a_frame_settles_the_estimates_that_arrived_after_it_before_giving_up() -> None:
    """An estimate with a near (not equal) stamp that arrived after its frame still pairs."""
    joiner: StampJoiner[str, str] = StampJoiner(["a"], tolerance=5, lateness=10, keep_events=True)
    done = joiner.add_gt(100, "g", arrival=0)
    done += joiner.add_estimate("a", 103, "e", arrival=14)  # waits until 29, the frame until 15
    done += joiner.add_gt(200, "h", arrival=16)  # the frame's wait is over
    assert [(f.stamp, f.estimates) for f in done] == [(100, {"a": (103, "e")})]
    joiner.flush()
    assert [e for e in joiner.events or [] if e.kind != "frame"] == [("dropped", "a", 200, 16)]


@dataclass(frozen=True)
class Message:
    """One message of a generated stream: ``method`` None for the ground truth."""

    method: str | None
    stamp: int
    arrival: int
    frame: int
    """The frame it belongs to (-1: an estimate of no frame)."""


@st.composite
def streams(draw: st.DrawFn) -> tuple[list[Message], int, int]:
    """Random streams: stamps far from the arrival clock, late methods, missing messages.

    Ground-truth stamps are ``period`` apart, estimates within the tolerance of their frame's
    stamp (or, for estimates of no frame, half a period away), so each estimate has one
    candidate frame and pairs with it exactly when both arrived within tolerance + lateness.
    """
    tolerance = 10
    lateness = draw(st.integers(0, 300))
    period = draw(st.integers(4 * tolerance, 200))
    offset = draw(st.integers(-(10**12), 10**12))  # stamps minus arrival clock
    frames = draw(st.integers(1, 25))
    methods = {m: draw(st.integers(0, 600)) for m in ("a", "b", "c")}  # latency of each
    messages: list[Message] = []
    for i in range(frames):
        arrival = i * period + draw(st.integers(0, 60))
        stamp = offset + i * period
        if draw(st.booleans()) or i == 0:
            messages.append(Message(None, stamp, arrival, i))
            if draw(st.integers(0, 9)) == 0:  # the same frame again, soon or much later
                again = draw(st.sampled_from([1, draw(st.integers(0, 3000))]))
                messages.append(Message(None, stamp, arrival + again, i))
        for method, latency in methods.items():
            if draw(st.integers(0, 4)) == 0:
                continue  # this method misses the frame
            jitter = draw(st.sampled_from([0, 0, draw(st.integers(-tolerance, tolerance))]))
            late = arrival + latency + draw(st.integers(-40, 60))
            messages.append(Message(method, stamp + jitter, late, i))
            if draw(st.integers(0, 9)) == 0:  # an estimate of no frame
                messages.append(Message(method, stamp + period // 2, late + 3, -1))
    messages.sort(key=lambda m: m.arrival)  # as a bag yields them: in log time
    return messages, tolerance, lateness


def join_stream(
    messages: list[Message], tolerance: int, lateness: int, seen: frozenset[int] | None = None
) -> tuple[list[tuple[int, int, dict[str, int]]], list[tuple[str, str, int, int]]]:
    """One pass: (arrival, stamp, method → estimate stamp) of every frame set, every event.

    ``seen``: a slice's GT stamps kept by the slices before (None: one pass, default memory).
    """
    joiner: StampJoiner[int, int] = (
        StampJoiner(["a", "b", "c"], tolerance, lateness, True)
        if seen is None
        else StampJoiner(["a", "b", "c"], tolerance, lateness, True, repeat_memory=None, seen=seen)
    )
    frame_sets = []
    for message in messages:
        if message.method is None:
            frame_sets += joiner.add_gt(message.stamp, message.frame, message.arrival)
        else:
            frame_sets += joiner.add_estimate(
                message.method, message.stamp, message.frame, message.arrival
            )
    frame_sets += joiner.flush()
    rows = [(f.arrival, f.stamp, {m: s for m, (s, _) in f.estimates.items()}) for f in frame_sets]
    return rows, [tuple(event) for event in joiner.events or []]


def sliced(
    messages: list[Message], tolerance: int, lateness: int, slice_length: int
) -> tuple[list[tuple[int, int, dict[str, int]]], list[tuple[str, str, int, int]]]:
    """Units of ``slice_length`` arrival time, as ``dispeval bag`` cuts a bag: each reads
    tolerance + lateness beyond its edges (and the GT of one margin more before), keeps what
    arrived inside it, and runs again with the stamps of frames it took that an earlier unit
    kept an earlier copy of as repeats."""
    margin = tolerance + lateness
    first, last = messages[0].arrival, messages[-1].arrival
    edges = list(range(first + slice_length, last + 1, slice_length))
    bounds = list(zip([-(2**62), *edges], [*edges, 2**62], strict=True))
    rows: list[tuple[int, int, dict[str, int]]] = []
    events: list[tuple[str, str, int, int]] = []
    kept: dict[int, int] = {}  # stamp → arrival of the first copy kept
    for start, stop in bounds:
        seen: frozenset[int] = frozenset()
        while True:
            read = [
                m
                for m in messages
                if start - margin <= m.arrival < stop + margin
                or (m.method is None and start - 2 * margin <= m.arrival < start - margin)
            ]
            unit_rows, unit_events = join_stream(read, tolerance, lateness, seen)
            taken = [(e[2], e[3]) for e in unit_events if e[0] == "frame"]
            again = {stamp for stamp, arrival in taken if kept.get(stamp, arrival) < arrival}
            if not again:
                break
            seen |= again
        unit_rows = [row for row in unit_rows if start <= row[0] < stop]
        unit_events = [event for event in unit_events if start <= event[3] < stop]
        rows += unit_rows
        events += unit_events
        for arrival, stamp, _ in unit_rows:
            kept.setdefault(stamp, arrival)
        for kind, _, stamp, arrival in unit_events:
            if kind == "dropped":
                kept.setdefault(stamp, arrival)
    return rows, events


def by_definition(
    messages: list[Message], tolerance: int, lateness: int
) -> tuple[dict[int, dict[str, int]], Counter[tuple[str, str]]]:
    """The join from its definition: an estimate pairs with its frame's (first) GT message when
    they arrived within tolerance + lateness of each other; the rest is unmatched or dropped."""
    gt = {}
    repeated = 0
    for message in messages:
        if message.method is None:
            repeated += message.frame in gt
            gt.setdefault(message.frame, message)
    joined: dict[int, dict[str, int]] = {}
    counts: Counter[tuple[str, str]] = Counter({("repeated", ""): repeated})
    for message in messages:
        if message.method is None:
            continue
        frame = gt.get(message.frame)
        if frame is not None and abs(message.arrival - frame.arrival) <= tolerance + lateness:
            joined.setdefault(frame.stamp, {})[message.method] = message.stamp
        else:
            counts["unmatched", message.method] += 1
    for frame in gt.values():
        for method in ("a", "b", "c"):
            counts["dropped", method] += method not in joined.get(frame.stamp, {})
    return joined, +counts


EDGE_REPEAT = (
    [
        Message(None, 0, 0, 0),
        Message(None, 0, 1, 0),  # the frame again, just inside the next slice's reading
        Message("c", 0, 11, 0),
        Message("c", 20, 14, -1),
    ],
    10,
    0,
)
"""A slice that reads the second copy but not the first must not pair it (found by hypothesis)."""


@settings(max_examples=300, deadline=None)
@example(stream=EDGE_REPEAT, slice_lengths=[1])
@given(stream=streams(), slice_lengths=st.lists(st.integers(1, 800), min_size=1, max_size=3))
def test_slices_of_a_stream_join_as_one_pass(
    stream: tuple[list[Message], int, int], slice_lengths: list[int]
) -> None:
    """Whatever the slicing, every estimate counts once (matched or unmatched) and every GT
    frame once per method (matched or dropped), as one pass and as the definition say."""
    messages, tolerance, lateness = stream
    rows, events = join_stream(messages, tolerance, lateness)
    joined, counts = by_definition(messages, tolerance, lateness)
    assert {stamp: estimates for _, stamp, estimates in rows} == joined
    assert len(rows) == len(joined)  # each frame set once
    assert Counter((k, m) for k, m, _, _ in events if k != "frame") == counts
    for length in [*slice_lengths, tolerance + lateness, 10**9]:
        slice_rows, slice_events = sliced(messages, tolerance, lateness, length)
        assert sorted(slice_rows, key=repr) == sorted(rows, key=repr), length
        assert sorted(slice_events) == sorted(events), length
