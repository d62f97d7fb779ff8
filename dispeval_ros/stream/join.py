"""Join ground-truth frames with every method's estimates by header stamp (no transport).

Two clocks: which ground-truth frame an estimate belongs to is decided by header stamps
(``tolerance``), how long anything waits by the *arrival* clock (the bag's log time, the
receipt time live), so that the outcome does not depend on how far stamps are from the
clock (re-recorded bags, simulated time, converted datasets).

Exact stamps pair at once; otherwise an estimate pairs with the nearest ground-truth frame
within ``tolerance`` that this method has not used yet. A ground-truth frame waits for
estimates, and an estimate waits for a ground-truth frame, until the arrival clock has passed
its own arrival by ``tolerance + lateness``; a frame that gives up counts its missing methods
*dropped* (first settling the estimates that could still pair with it), an estimate that gives
up counts *unmatched*. Each message first advances the clock and settles what expired before
it, in arrival order, so a frame and an estimate pair exactly when they arrived within
``tolerance + lateness`` of each other: the same in one pass as in a slice read with that
margin. Work per message is O(log n + m) for n buffered messages and m methods (plus the
list moves of inserting into and removing from sorted lists): no all-pairs search.
"""

from __future__ import annotations

import bisect
from collections import deque
from collections.abc import Collection, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Generic, NamedTuple, TypeVar

from dispeval_ros.errors import ConfigurationError

G = TypeVar("G")
E = TypeVar("E")

ARRIVAL_CLOCK = "the arrival clock (log time in a bag, receipt time live)"
LATENESS_RULE = (
    f"how long, beyond the tolerance and on {ARRIVAL_CLOCK}, a ground-truth frame waits for "
    "its estimates and an estimate for its ground-truth frame; then a frame still missing a "
    "method counts it dropped, an estimate still without a frame counts unmatched"
)
"""What lateness means: the one text of the CLI help and the ROS parameter description."""
REPEAT_MEMORY_NS = 60_000_000_000
"""How long (in arrival time, after its wait) a ground-truth stamp done with is remembered, so
that the same stamp arriving again (a bag holding a frame twice) is ignored instead of scored
twice."""


@dataclass
class JoinCounts:
    """Per method: estimates paired, estimates without ground truth, GT frames without estimate."""

    matched: int = 0
    unmatched: int = 0
    dropped: int = 0


@dataclass
class FrameSet(Generic[G, E]):
    """One ground-truth frame and the estimates paired with it (method → (stamp, payload)).

    ``arrival``: when the ground-truth frame arrived (the clock of units and lateness);
    ``arrivals``: when each estimate arrived, on that clock (its delay is that minus its stamp).
    """

    stamp: int
    gt: G
    estimates: dict[str, tuple[int, E]] = field(default_factory=dict)
    arrival: int = 0
    arrivals: dict[str, int] = field(default_factory=dict)


class JoinEvent(NamedTuple):
    """An estimate left unmatched, a frame a method dropped, or a GT frame repeated.

    ``arrival`` is that of the message the event is about (the estimate, the GT frame).
    """

    kind: str
    method: str
    stamp: int
    arrival: int


@dataclass
class _Pending(Generic[G, E]):
    frame_set: FrameSet[G, E]
    waiting: set[str]


@dataclass(eq=False)
class _Waiting(Generic[E]):
    """An estimate waiting for its ground-truth frame."""

    method: str
    stamp: int
    arrival: int
    payload: E
    settled: bool = False
    received: int = 0
    """Its own arrival (``arrival`` is the clock then, which never goes back): its delay's."""


class StampJoiner(Generic[G, E]):
    """Streaming join of one ground-truth stream with several estimate streams.

    Stamps and arrivals are integers (nanoseconds). ``tolerance`` is in stamp time; a message
    waits ``tolerance + lateness`` of arrival time (pipeline latency, reordering between
    topics). Without an arrival, a message arrives at its stamp (streams stamped on arrival).
    """

    def __init__(
        self,
        methods: Sequence[str],
        tolerance: int,
        lateness: int = 0,
        keep_events: bool = False,
        *,
        repeat_memory: int | None = REPEAT_MEMORY_NS,
        seen: Collection[int] = (),
    ) -> None:
        """Join ``methods`` with the ground truth.

        ``repeat_memory``: see :data:`REPEAT_MEMORY_NS` (None: every stamp is remembered);
        ``seen``: GT stamps done with before this join started (their frames are repeats).
        """
        if not methods:
            raise ConfigurationError("at least one method is needed to join with the ground truth")
        if tolerance < 0 or lateness < 0:
            raise ConfigurationError("the sync tolerance and lateness must not be negative")
        self.methods = tuple(methods)
        self.tolerance = int(tolerance)
        self.lateness = int(lateness)
        self.counts = {method: JoinCounts() for method in self.methods}
        self._gt_stamps: list[int] = []
        self._gt: dict[int, _Pending[G, E]] = {}
        self._gt_order: deque[tuple[int, int]] = deque()
        """(arrival, stamp) of GT frames in arrival order (those done with are skipped)."""
        self._estimates: dict[str, list[_Waiting[E]]] = {m: [] for m in self.methods}
        """Per method, waiting estimates by stamp (equal stamps in arrival order)."""
        self._estimate_order: deque[_Waiting[E]] = deque()
        """Every method's waiting estimates in arrival order (settled ones are skipped)."""
        self._clock: int | None = None
        self.repeat_memory = repeat_memory
        self._emitted: set[int] = set(seen)
        self._emitted_order: deque[tuple[int, int]] = deque()
        self.repeated_gt = 0
        """Ground-truth frames ignored because their stamp was already seen (the first stands)."""
        self.events: list[JoinEvent] | None = [] if keep_events else None
        """With ``keep_events``: every GT frame taken ("frame"), unmatched estimate, dropped
        frame and repeated GT frame, for slicing."""

    @property
    def wait(self) -> int:
        """How long (arrival time) a message waits for the messages it pairs with."""
        return self.tolerance + self.lateness

    # -- input ------------------------------------------------------------------------------

    def add_gt(self, stamp: int, payload: G, arrival: int | None = None) -> list[FrameSet[G, E]]:
        """A ground-truth frame; returns the frame sets this completes or retires."""
        now, done = self._advance(stamp if arrival is None else arrival)
        if stamp in self._gt or stamp in self._emitted:  # a repeated GT stamp: the first stands
            self.repeated_gt += 1
            self._event("repeated", "", stamp, now)
            return done
        bisect.insort(self._gt_stamps, stamp)
        self._event("frame", "", stamp, now)
        self._gt[stamp] = _Pending(FrameSet(stamp, payload, arrival=now), set(self.methods))
        self._gt_order.append((now, stamp))
        for method, queue in self._estimates.items():
            index = bisect.bisect_left(queue, stamp, key=lambda item: item.stamp)
            if index < len(queue) and queue[index].stamp == stamp:
                waiting = queue.pop(index)
                waiting.settled = True
                done.extend(self._pair(method, stamp, (stamp, waiting.payload), waiting.received))
        return done

    def add_estimate(
        self, method: str, stamp: int, payload: E, arrival: int | None = None
    ) -> list[FrameSet[G, E]]:
        """An estimate of ``method``; returns the frame sets this completes or retires."""
        if method not in self._estimates:
            raise ConfigurationError(f"unknown method '{method}'; known: {', '.join(self.methods)}")
        received = stamp if arrival is None else int(arrival)
        now, done = self._advance(received)
        pending = self._gt.get(stamp)
        if pending is not None and method in pending.waiting:
            done.extend(self._pair(method, stamp, (stamp, payload), received))
            return done
        waiting = _Waiting(method, stamp, now, payload, received=received)
        queue = self._estimates[method]
        queue.insert(bisect.bisect_right(queue, stamp, key=lambda item: item.stamp), waiting)
        self._estimate_order.append(waiting)
        return done

    def flush(self) -> list[FrameSet[G, E]]:
        """End of stream: settle every waiting estimate and retire every GT frame, in order."""
        return self._expire(None)

    @property
    def buffered(self) -> int:
        """Frames held (GT frames waiting for estimates plus estimates waiting for GT)."""
        return len(self._gt) + sum(len(queue) for queue in self._estimates.values())

    def drop_oldest(self) -> FrameSet[G, E] | None:
        """Discard the oldest waiting GT frame (bounded memory); its methods count it dropped."""
        oldest = self._oldest_gt()
        if oldest is None:
            return None
        stamp = oldest[1]
        pending = self._gt[stamp]
        self._forget(stamp)
        for method in self.methods:
            if method not in pending.waiting:  # its estimate is lost with it
                self.counts[method].matched -= 1
            self.counts[method].dropped += 1
            self._event("dropped", method, stamp, pending.frame_set.arrival)
        return pending.frame_set

    # -- internals --------------------------------------------------------------------------

    def _advance(self, arrival: int) -> tuple[int, list[FrameSet[G, E]]]:
        """Move the clock to ``arrival`` (never back) and settle what expired before it."""
        now = arrival if self._clock is None else max(self._clock, int(arrival))
        self._clock = now
        horizon = now - self.wait
        memory = self.repeat_memory
        while memory is not None and self._emitted_order:
            if self._emitted_order[0][0] >= horizon - memory:
                break
            self._emitted.discard(self._emitted_order.popleft()[1])
        return now, self._expire(horizon)

    def _expire(self, horizon: int | None) -> list[FrameSet[G, E]]:
        """Settle, oldest arrival first, everything that arrived before ``horizon`` (all if None).

        At equal arrivals the estimate goes first (it may still pair with that frame).
        """
        done: list[FrameSet[G, E]] = []
        while True:
            estimate = self._oldest_estimate()
            gt = self._oldest_gt()
            if estimate is not None and (gt is None or estimate.arrival <= gt[0]):
                if horizon is not None and estimate.arrival >= horizon:
                    return done
                done.extend(self._settle(estimate))
            elif gt is not None:
                if horizon is not None and gt[0] >= horizon:
                    return done
                done.extend(self._retire(gt[1]))
            else:
                return done

    def _oldest_estimate(self) -> _Waiting[E] | None:
        order = self._estimate_order
        while order and order[0].settled:
            order.popleft()
        return order[0] if order else None

    def _oldest_gt(self) -> tuple[int, int] | None:
        order = self._gt_order
        while order and (
            order[0][1] not in self._gt or self._gt[order[0][1]].frame_set.arrival != order[0][0]
        ):
            order.popleft()
        return order[0] if order else None

    def _settle(self, waiting: _Waiting[E]) -> list[FrameSet[G, E]]:
        """Pair a waiting estimate with its nearest free GT frame, or count it unmatched."""
        queue = self._estimates[waiting.method]
        index = bisect.bisect_left(queue, waiting.stamp, key=lambda item: item.stamp)
        while queue[index] is not waiting:
            index += 1
        queue.pop(index)
        waiting.settled = True
        gt_stamp = self._nearest_free_gt(waiting.method, waiting.stamp)
        if gt_stamp is None:
            self.counts[waiting.method].unmatched += 1
            self._event("unmatched", waiting.method, waiting.stamp, waiting.arrival)
            return []
        estimate = (waiting.stamp, waiting.payload)
        return list(self._pair(waiting.method, gt_stamp, estimate, waiting.received))

    def _pair(
        self, method: str, gt_stamp: int, estimate: tuple[int, E], arrival: int
    ) -> Iterable[FrameSet[G, E]]:
        pending = self._gt[gt_stamp]
        pending.frame_set.estimates[method] = estimate
        pending.frame_set.arrivals[method] = arrival
        pending.waiting.discard(method)
        self.counts[method].matched += 1
        if not pending.waiting:
            self._forget(gt_stamp)
            return [pending.frame_set]
        return []

    def _forget(self, stamp: int) -> None:
        """A GT stamp that is done with: the same stamp again is a repeat, not a new frame."""
        pending = self._gt.pop(stamp)
        self._gt_stamps.pop(bisect.bisect_left(self._gt_stamps, stamp))
        self._emitted.add(stamp)
        self._emitted_order.append((pending.frame_set.arrival, stamp))

    def _nearest_free_gt(self, method: str, stamp: int) -> int | None:
        """The GT stamp nearest to ``stamp`` within tolerance still waiting for ``method``."""
        low = bisect.bisect_left(self._gt_stamps, stamp - self.tolerance)
        high = bisect.bisect_right(self._gt_stamps, stamp + self.tolerance)
        best: int | None = None
        for candidate in self._gt_stamps[low:high]:
            if method in self._gt[candidate].waiting and (
                best is None or abs(candidate - stamp) < abs(best - stamp)
            ):
                best = candidate
        return best

    def _event(self, kind: str, method: str, stamp: int, arrival: int) -> None:
        if self.events is not None:
            self.events.append(JoinEvent(kind, method, stamp, arrival))

    def _retire(self, stamp: int) -> list[FrameSet[G, E]]:
        """A GT frame's wait is over: its missing methods count it dropped.

        The estimates still waiting that could pair with it are settled first (in arrival
        order, while the frame still waits for their method): an estimate that arrived after
        the frame, within the wait, has had its chance.
        """
        pending = self._gt[stamp]
        done: list[FrameSet[G, E]] = []
        for method in sorted(pending.waiting):
            queue = self._estimates[method]
            low = bisect.bisect_left(queue, stamp - self.tolerance, key=lambda item: item.stamp)
            high = bisect.bisect_right(queue, stamp + self.tolerance, key=lambda item: item.stamp)
            candidates = sorted(queue[low:high], key=lambda item: item.arrival)
            for waiting in candidates:
                if method not in pending.waiting:
                    break
                done.extend(self._settle(waiting))
        if stamp not in self._gt:  # completed by those estimates
            return done
        for method in sorted(pending.waiting):
            self.counts[method].dropped += 1
            self._event("dropped", method, stamp, pending.frame_set.arrival)
        self._forget(stamp)
        return done + ([pending.frame_set] if pending.frame_set.estimates else [])
