"""Live evaluation: the evaluation core behind a bounded queue and one scoring thread.

Transport callbacks call :meth:`LiveEvaluator.push`, which only joins by stamp (microseconds;
the receipt time is the join's arrival clock, see :mod:`~dispeval_ros.stream.join`, and each
estimate's delay is its receipt minus its header stamp) and never
blocks: joined frames wait in a bounded queue, and when scoring cannot keep up the
oldest waiting frame is dropped and counted for every method in it. A worker thread scores
and hands each :class:`~dispeval_ros.stream.core.FrameResult` to the front end's callback.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from dispeval_ros.stream.core import CoreConfig, EvaluationCore, FrameResult, MethodCounts
from dispeval_ros.stream.join import FrameSet
from dispeval_ros.stream.pairs import LIVE_MOTION_GRACE_S, LIVE_MOTION_STALE_NS

MOTION_POLL_S = 0.002
"""How often a pair waiting for /tf looks again (s)."""


@dataclass
class LiveStats:
    """Counters and latencies (seconds, from the frame's last message to its result)."""

    queue_drops: int = 0
    results: int = 0
    latencies: list[float] = field(default_factory=list)
    motion_waits: int = 0
    """Pairs that waited (or wait now) for /tf at their later stamp (at most
    :data:`LIVE_MOTION_GRACE_S`)."""


class LiveEvaluator:
    """Thread-safe, non-blocking front of :class:`EvaluationCore` for live streams.

    With ``workers`` > 1, results may be handed over out of stamp order; with a pair stage
    (``temporal``, ``egomotion``) or flicker windows they are handed over in the join's order,
    each after its pairs and windows are scored.
    """

    def __init__(
        self,
        config: CoreConfig,
        on_result: Callable[[FrameResult], None],
        *,
        queue_size: int = 4,
        max_buffered: int = 256,
        error_images: bool = False,
        workers: int = 1,
        keep_latencies: int = 100_000,
        clock: Callable[[], float] = time.monotonic,
        epoch: float | None = None,
    ) -> None:
        """``clock`` (s) times the queue; ``epoch`` (s) added to it reads the stamps' clock.

        That gives receipt times (None: the wall clock's offset now, as stamps of system time
        are; a monotonic clock so shifted never jumps back as the wall clock may).
        """
        self.epoch = time.time() - clock() if epoch is None else epoch
        self.core = EvaluationCore(config, error_images=error_images)
        self.on_result = on_result
        self.queue_size = max(1, queue_size)
        self.max_buffered = max_buffered
        self.stats = LiveStats()
        self._keep_latencies = keep_latencies
        self._clock = clock
        self._lock = threading.Lock()
        self._pair_lock = threading.Lock()
        self._taken = 0  # frames taken from the queue, and handed over in that order (pairs)
        self._handed = 0
        self._last_stamp = 0  # of the last result handed over in order (flicker's tail)
        self._finished: dict[int, FrameResult | None] = {}
        self._ready = threading.Condition(self._lock)
        self._queue: deque[tuple[FrameSet[Any, Any], float]] = deque()
        self._dropped: dict[str, int] = dict.fromkeys(config.methods, 0)
        self._stopping = False
        self._busy = 0
        # Several workers score frames at once: the compiled kernels release the GIL, so a
        # second core takes the next frame while the first is still being scored.
        self._workers = [
            threading.Thread(target=self._run, name=f"dispeval-scoring-{i}", daemon=True)
            for i in range(max(1, workers))
        ]
        for worker in self._workers:
            worker.start()

    # -- transport side ---------------------------------------------------------------------

    def push(self, topic: str, msg: Any, received: int | None = None) -> None:
        """Take one message (from any thread); never blocks on scoring.

        ``received`` (ns, the header stamps' clock): when it was received, if the transport
        knows (give it for every message or for none); else now, by ``clock`` + ``epoch``.
        """
        arrived = self._clock()
        receipt = round((arrived + self.epoch) * 1e9) if received is None else int(received)
        with self._lock:
            if self._stopping:
                return
            ready = self.core.push(topic, msg, receipt)  # the join's arrival clock
            while self.core.joiner.buffered > self.max_buffered:
                if self.core.joiner.drop_oldest() is None:
                    break
            for frame_set in ready:
                self._enqueue(frame_set, arrived)

    def _enqueue(self, frame_set: FrameSet[Any, Any], arrived: float) -> None:
        if len(self._queue) >= self.queue_size:
            oldest, _ = self._queue.popleft()
            self.stats.queue_drops += 1
            for method in oldest.estimates:
                self._dropped[method] += 1
        self._queue.append((frame_set, arrived))
        self._ready.notify()

    # -- scoring side -----------------------------------------------------------------------

    def _run(self) -> None:
        while True:
            with self._lock:
                while not self._queue and not self._stopping:
                    self._ready.wait()
                if not self._queue and self._stopping:
                    return
                frame_set, arrived = self._queue.popleft()
                self._busy += 1
                turn, self._taken = self._taken, self._taken + 1  # the join's order
            result: FrameResult | None = None
            try:
                result = self.core.score(frame_set)
                if not self.core.ordered:
                    self.on_result(result)
            finally:
                if self.core.ordered:
                    self._in_order(turn, result)
                with self._lock:
                    self._busy -= 1
                    self.stats.results += 1
                    if len(self.stats.latencies) < self._keep_latencies:
                        self.stats.latencies.append(self._clock() - arrived)
                    self._ready.notify_all()

    def _in_order(self, turn: int, result: FrameResult | None) -> None:
        """With pairs: each result through the pair stage and out, in the order taken.

        Frames scored side by side finish in any order; the pair stage needs them in the
        join's, so a result waits here for those taken before it (None: it raised).
        """
        with self._pair_lock:
            self._finished[turn] = result
            while self._handed in self._finished:
                ready = self._finished.pop(self._handed)
                self._handed += 1
                if ready is not None:
                    self._await_motion(ready)
                    self.core.window(self.core.pair(ready))
                    self._last_stamp = ready.stamp
                    self.on_result(ready)

    def _await_motion(self, result: FrameResult) -> None:
        """Give /tf that lags the frame a moment to reach its stamp before its pair is scored.

        Only while /tf is flowing (its newest sample within :data:`LIVE_MOTION_STALE_NS` of
        the frame); at most :data:`LIVE_MOTION_GRACE_S`.
        """
        motion, frame = self.core.motion, result.pair_input
        if motion is None or frame is None or not frame.camera_frame or self._stopping:
            return  # (stopping: no /tf is coming any more)
        deadline = self._clock() + LIVE_MOTION_GRACE_S
        for attempt in itertools.count():
            until = motion.answers_until(frame.camera_frame)
            behind = None if until is None else result.stamp - until
            if behind is None or behind <= 0 or behind > LIVE_MOTION_STALE_NS:
                return
            if self._clock() >= deadline:
                return
            if attempt == 0:
                self.stats.motion_waits += 1
            time.sleep(MOTION_POLL_S)

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Block until every queued frame is scored (for tests and orderly shutdown)."""
        deadline = None if timeout is None else self._clock() + timeout
        with self._lock:
            while self._queue or self._busy:
                remaining = None if deadline is None else deadline - self._clock()
                if remaining is not None and remaining <= 0:
                    return False
                self._ready.wait(remaining)
        return True

    def stop(self, flush: bool = True, timeout: float | None = None) -> None:
        """Stop taking messages; with ``flush``, join and score everything still waiting."""
        with self._lock:
            if flush:
                now = self._clock()
                for frame_set in self.core.flush():
                    self._queue.append((frame_set, now))
            else:
                self._queue.clear()
            self._stopping = True
            self._ready.notify_all()
        for worker in self._workers:
            worker.join(timeout)
        if flush:
            self._finish_windows()

    def _finish_windows(self) -> None:
        """The flicker windows still open at the end, handed over as a frame of their own.

        It has no scores (each window is on a status of its own: :func:`~dispeval_ros.stream.
        vectors.result_statuses`) and is stamped 1 ns after the last frame handed over: no
        frame's stamp, so no summarizer takes it for a frame seen again (a new sequence).
        """
        with self._pair_lock:
            tail = self.core.finish_windows()
            if tail is None or not (tail.windows or tail.problems):
                return
            stamp = self._last_stamp + 1
            result = FrameResult(stamp, {}, {}, list(tail.problems), flicker=list(tail.windows))
        self.on_result(result)

    def counts(self) -> dict[str, MethodCounts]:
        """Per method: matched (scored), unmatched, dropped (incl. queue drops), failed."""
        with self._lock:
            counts = self.core.counts()
            for method, dropped in self._dropped.items():
                counts[method].matched -= dropped
                counts[method].dropped += dropped
            return counts
