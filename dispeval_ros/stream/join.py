"""Join ground-truth frames with every method's estimates by header stamp (no transport).

Exact stamps pair at once; otherwise an estimate pairs with the nearest ground-truth frame
within ``tolerance`` that this method has not used yet, decided once the stream has moved
``tolerance + lateness`` past it (so every candidate has had time to arrive). A ground-truth
frame is emitted as soon as every method has an estimate for it, or when it can no longer get
one (then the missing methods count it as *dropped*). Work per message is O(log n + m) for n
buffered frames and m methods: no all-pairs search.
"""

from __future__ import annotations

import bisect
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Generic, TypeVar

from dispeval_ros.errors import ConfigurationError

G = TypeVar("G")
E = TypeVar("E")

REPEAT_MEMORY_NS = 60_000_000_000
"""How long (in stamp time) an emitted ground-truth stamp is remembered, so that the same
stamp arriving again (a bag holding a frame twice) is ignored instead of scored twice."""


@dataclass
class JoinCounts:
    """Per method: estimates paired, estimates without ground truth, GT frames without estimate."""

    matched: int = 0
    unmatched: int = 0
    dropped: int = 0


@dataclass
class FrameSet(Generic[G, E]):
    """One ground-truth frame and the estimates paired with it (method → (stamp, payload))."""

    stamp: int
    gt: G
    estimates: dict[str, tuple[int, E]] = field(default_factory=dict)


@dataclass
class _Pending(Generic[G, E]):
    frame_set: FrameSet[G, E]
    waiting: set[str]


class StampJoiner(Generic[G, E]):
    """Streaming join of one ground-truth stream with several estimate streams.

    Stamps are integers (nanoseconds). ``lateness`` is how far behind the newest stamp seen
    a message may still arrive (pipeline latency, reordering between topics).
    """

    def __init__(
        self, methods: Sequence[str], tolerance: int, lateness: int = 0, keep_events: bool = False
    ) -> None:
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
        self._estimates: dict[str, list[tuple[int, E]]] = {m: [] for m in self.methods}
        self._watermark: int | None = None
        self._emitted: set[int] = set()
        self._emitted_order: deque[int] = deque()
        self.repeated_gt = 0
        """Ground-truth frames ignored because their stamp was already seen (the first stands)."""
        self.events: list[tuple[str, str, int]] | None = [] if keep_events else None
        """With ``keep_events``: every ("unmatched" | "dropped", method, stamp), for slicing."""

    # -- input ------------------------------------------------------------------------------

    def add_gt(self, stamp: int, payload: G) -> list[FrameSet[G, E]]:
        """A ground-truth frame; returns the frame sets this completes or retires."""
        if stamp in self._gt or stamp in self._emitted:  # a repeated GT stamp: the first stands
            self.repeated_gt += 1
            self._event("repeated", "", stamp)
            return self._advance(stamp)
        bisect.insort(self._gt_stamps, stamp)
        self._gt[stamp] = _Pending(FrameSet(stamp, payload), set(self.methods))
        done: list[FrameSet[G, E]] = []
        for method, queue in self._estimates.items():
            index = bisect.bisect_left(queue, stamp, key=lambda item: item[0])
            if index < len(queue) and queue[index][0] == stamp:
                estimate = queue.pop(index)
                done.extend(self._pair(method, stamp, estimate))
        return done + self._advance(stamp)

    def add_estimate(self, method: str, stamp: int, payload: E) -> list[FrameSet[G, E]]:
        """An estimate of ``method``; returns the frame sets this completes or retires."""
        if method not in self._estimates:
            raise ConfigurationError(f"unknown method '{method}'; known: {', '.join(self.methods)}")
        pending = self._gt.get(stamp)
        done: list[FrameSet[G, E]] = []
        if pending is not None and method in pending.waiting:
            done.extend(self._pair(method, stamp, (stamp, payload)))
        else:
            queue = self._estimates[method]
            queue.insert(
                bisect.bisect_right(queue, stamp, key=lambda item: item[0]), (stamp, payload)
            )
        return done + self._advance(stamp)

    def flush(self) -> list[FrameSet[G, E]]:
        """End of stream: resolve every waiting estimate and retire every GT frame."""
        done = self._resolve_estimates(None)
        for stamp in list(self._gt_stamps):
            done.extend(self._retire(stamp))
        return done

    @property
    def buffered(self) -> int:
        """Frames held (GT frames waiting for estimates plus estimates waiting for GT)."""
        return len(self._gt) + sum(len(queue) for queue in self._estimates.values())

    def drop_oldest(self) -> FrameSet[G, E] | None:
        """Discard the oldest waiting GT frame (bounded memory); its methods count it dropped."""
        if not self._gt_stamps:
            return None
        stamp = self._gt_stamps.pop(0)
        pending = self._gt.pop(stamp)
        self._remember(stamp)
        for method in self.methods:
            if method not in pending.waiting:  # its estimate is lost with it
                self.counts[method].matched -= 1
            self.counts[method].dropped += 1
            self._event("dropped", method, stamp)
        return pending.frame_set

    # -- internals --------------------------------------------------------------------------

    def _pair(
        self, method: str, gt_stamp: int, estimate: tuple[int, E]
    ) -> Iterable[FrameSet[G, E]]:
        pending = self._gt[gt_stamp]
        pending.frame_set.estimates[method] = estimate
        pending.waiting.discard(method)
        self.counts[method].matched += 1
        if not pending.waiting:
            self._forget(gt_stamp)
            return [pending.frame_set]
        return []

    def _forget(self, stamp: int) -> None:
        del self._gt[stamp]
        self._gt_stamps.pop(bisect.bisect_left(self._gt_stamps, stamp))
        self._remember(stamp)

    def _remember(self, stamp: int) -> None:
        """A GT stamp that is done with: the same stamp again is a repeat, not a new frame."""
        self._emitted.add(stamp)
        self._emitted_order.append(stamp)

    def _advance(self, stamp: int) -> list[FrameSet[G, E]]:
        if self._watermark is None or stamp > self._watermark:
            self._watermark = stamp
        horizon = self._watermark - self.tolerance - self.lateness
        while self._emitted_order and self._emitted_order[0] < horizon - REPEAT_MEMORY_NS:
            self._emitted.discard(self._emitted_order.popleft())
        done = self._resolve_estimates(horizon)
        while self._gt_stamps and self._gt_stamps[0] + self.tolerance < horizon:
            done.extend(self._retire(self._gt_stamps[0]))
        return done

    def _resolve_estimates(self, horizon: int | None) -> list[FrameSet[G, E]]:
        """Pair (or give up on) every estimate older than ``horizon`` (all if None)."""
        done: list[FrameSet[G, E]] = []
        for method, queue in self._estimates.items():
            while queue and (horizon is None or queue[0][0] < horizon):
                estimate = queue.pop(0)
                gt_stamp = self._nearest_free_gt(method, estimate[0])
                if gt_stamp is None:
                    self.counts[method].unmatched += 1
                    self._event("unmatched", method, estimate[0])
                else:
                    done.extend(self._pair(method, gt_stamp, estimate))
        return done

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

    def _event(self, kind: str, method: str, stamp: int) -> None:
        if self.events is not None:
            self.events.append((kind, method, stamp))

    def _retire(self, stamp: int) -> list[FrameSet[G, E]]:
        pending = self._gt[stamp]
        for method in sorted(pending.waiting):
            self.counts[method].dropped += 1
            self._event("dropped", method, stamp)
        self._forget(stamp)
        return [pending.frame_set] if pending.frame_set.estimates else []
