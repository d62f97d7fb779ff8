"""The stamp joiner: exact pairs, nearest within tolerance, drops and unmatched counts."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
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
    assert joiner.events == [("dropped", "a", 0, 0)]


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
