"""The summarizer on DDS: ``/dispeval/scores`` in, results database and ``/dispeval/groups`` out.

Every ``DiagnosticArray`` on ``/dispeval/scores`` (reliable, keep-all subscription) is turned
back into exact :class:`~dispeval_ros.core.Scores` (the statuses carry the raw sums) and given
to :class:`~dispeval_ros.stream.summarizer.SummarizerCore`, which writes the same results
database, ``frames.csv`` and ``summary.json`` as ``dispeval bag``. ERROR statuses without
values are the evaluator's per-frame problems; they are stored as the database's problems. The
evaluator's delivery records (:mod:`~dispeval_ros.stream.delivery`) give its unmatched, dropped
and failed counts, booked per sequence, and the scored frames that never arrived, counted as
dropped: as the rclpy summarizer does it, with the same ledger.
After every written unit the A* Groups go out on ``/dispeval/groups`` (reliable,
transient-local, so a late subscriber gets the latest at once). Recomputing the summary costs
more as the database grows, so the unit grows too when needed: summarising never takes more
than a tenth of the time (the evaluator in the same process keeps the CPU).

A stamp seen again, or one far behind the newest (the evaluator started a new pass), starts a
new sequence, so a looping stream never writes the same frame twice. "Far" is ``restart_ns``:
more than the reordering the evaluator itself causes (a frame waiting for a late estimate is
published up to ``tolerance + lateness`` after newer ones).
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any

from dispeval_ros.core import Scores
from dispeval_ros.core.egomotion import TemporalSums
from dispeval_ros.core.lidar_drift import DriftSums
from dispeval_ros.core.temporal import PairScores
from dispeval_ros.dds.diagnostics import diagnostic_array, records_of
from dispeval_ros.dds.evaluator import MIN_RESTART_NS
from dispeval_ros.dds.transport import DdsTransport, RawWriter, Received
from dispeval_ros.dds.wire import (
    DIAGNOSTIC_ARRAY,
    LATCHED,
    SUMMARIZER_INPUT,
)
from dispeval_ros.errors import InputError
from dispeval_ros.stream.delivery import CountsBook, Delivery, read_delivery
from dispeval_ros.stream.flicker import FlickerScore
from dispeval_ros.stream.summarizer import SummarizerConfig, SummarizerCore, group_statuses
from dispeval_ros.stream.topics import GROUPS_TOPIC, SCORES_TOPIC
from dispeval_ros.stream.vectors import (
    arrivals_of,
    read_pairs,
    read_problem,
    scores_from_status,
    window_only,
)
from dispeval_ros.summary import RunSummary

SUMMARY_SHARE = 0.1
"""At most this share of the wall time goes to recomputing the summary."""
MAX_PERIOD = 100_000


class DdsSummarizer:
    """Accumulate the scores published on a domain into a results database; publish groups.

    ``only_from`` restricts the input to one writer (``dispeval live`` listens to its own
    evaluator only, even when other evaluators publish on the same domain).
    """

    def __init__(
        self,
        transport: DdsTransport,
        config: SummarizerConfig,
        run_config: Mapping[str, object],
        *,
        only_from: RawWriter | None = None,
        restart_ns: int = 3 * MIN_RESTART_NS,
        on_summary: Callable[[RunSummary], None] | None = None,
        on_error: Callable[[str], None] | None = None,
    ) -> None:
        self.transport = transport
        self.typestore = transport.typestore
        self.core = SummarizerCore(config, run_config)
        self.on_summary = on_summary
        self._restart_ns = restart_ns
        self._only = None if only_from is None else _handle(only_from.entity.get_instance_handle())
        self._lock = threading.Condition()
        self._stamps: set[int] = set()
        self._newest: int | None = None
        self._book = CountsBook()
        """Counts and problems of the current sequence, booked when it closes."""
        self.received = 0
        self.ignored = 0
        self.frames = 0
        self.groups_writer = transport.writer(GROUPS_TOPIC, DIAGNOSTIC_ARRAY, LATCHED)
        self.reader = transport.reader(SCORES_TOPIC, DIAGNOSTIC_ARRAY, SUMMARIZER_INPUT)
        self.thread = transport.reader_thread("summarizer", on_error)
        self.thread.add(self.reader, self._on_scores)
        self._finished = False
        self._base_period = config.every_n
        self._last_unit: tuple[float, int] | None = None

    def start(self) -> None:
        """Start listening."""
        self.thread.start()

    # -- input (the reader thread) -----------------------------------------------------------

    def _on_scores(self, received: Received) -> None:
        if self._only is not None and _handle(received.info.publication_handle) != self._only:
            with self._lock:
                self.ignored += 1
            return
        stamp, records = records_of(received.msg)
        scores: dict[str, Scores] = {}
        arrivals: dict[str, tuple[int, int]] = {}
        pairs: dict[str, tuple[int, PairScores]] = {}
        motion: dict[str, tuple[int, TemporalSums]] = {}
        drift: dict[str, DriftSums] = {}
        flicker: dict[str, FlickerScore] = {}
        problems: list[tuple[str | None, str]] = []
        deliveries: list[Delivery] = []
        for record in records:
            try:
                delivery = read_delivery(record)
                if delivery is not None:
                    deliveries.append(delivery)
                    continue
                problem = read_problem(record)
                if problem is not None:
                    problems.append(problem)
                else:
                    if not window_only(record):
                        scores[record.name] = scores_from_status(record.values)
                    read_pairs(record, pairs, motion, drift=drift, flicker=flicker)
                arrivals.update(arrivals_of(record))  # failed estimates' too
            except InputError:
                continue  # not a dispeval status, or a malformed one
        self.add(
            stamp,
            scores,
            problems,
            deliveries,
            arrivals,
            pairs,
            motion,
            drift=drift,
            flicker=flicker,
        )

    def add(
        self,
        stamp: int,
        scores: Mapping[str, Scores],
        problems: list[tuple[str | None, str]] | None = None,
        deliveries: list[Delivery] | None = None,
        arrivals: Mapping[str, tuple[int, int]] | None = None,
        pairs: Mapping[str, tuple[int, PairScores]] | None = None,
        motion: Mapping[str, tuple[int, TemporalSums]] | None = None,
        *,
        drift: Mapping[str, DriftSums] | None = None,
        flicker: Mapping[str, FlickerScore] | None = None,
    ) -> None:
        """One frame (as it came off the wire): store, summarise every unit, publish groups.

        ``arrivals``: per method, (estimate stamp, arrival) from its status (the latency);
        ``pairs``, ``motion``: per method, the pair ending at the frame (``temporal``) and its
        ego-motion residual (``egomotion``); ``drift``: that pair's LiDAR drift; ``flicker``: per
        method, the flicker window closed with the frame.
        """
        summary = None
        with self._lock:
            self.received += 1
            if scores or problems:
                stale = self._newest is not None and stamp < self._newest - self._restart_ns
                if stamp in self._stamps or stale:
                    self._book_counts(closing=False)
                    self.core.new_sequence()
                    self._stamps.clear()
                    self._newest = None
                self._book.problems.extend((stamp, method, text) for method, text in problems or ())
            for delivery in deliveries or ():
                self._book.ledger.add(delivery, scores)
            if scores:
                self._stamps.add(stamp)
                self._newest = stamp if self._newest is None else max(self._newest, stamp)
                started = time.monotonic()
                summary = self.core.add(
                    stamp, scores, arrivals, pairs, motion, drift=drift, flicker=flicker
                )
                self.frames += 1
                if summary is not None:
                    self._adapt_period(time.monotonic() - started)
            elif arrivals or flicker:  # every estimate failed, or a window closed alone
                self.core.add(stamp, scores, arrivals, flicker=flicker)
            self._lock.notify_all()
        if summary is not None:
            self.publish_groups(summary)

    def _adapt_period(self, cost: float) -> None:
        """Keep summarising under ``SUMMARY_SHARE`` of the time (it grows with the database).

        A summary recomputes the models over everything stored, so its cost grows with the
        run; when one takes longer than its share of the time since the previous one, the
        period (frames per unit) grows accordingly. It never falls below ``--summary-every``.
        """
        now = time.monotonic()
        last, self._last_unit = self._last_unit, (now, self.frames)
        if last is None or self.frames <= last[1]:
            return
        per_frame = (now - last[0]) / (self.frames - last[1])
        if per_frame <= 0:
            return
        wanted = math.ceil(cost / (SUMMARY_SHARE * per_frame))
        period = max(self._base_period, min(wanted, MAX_PERIOD))
        if period != self.core.config.every_n:
            self.core.config = dataclasses.replace(self.core.config, every_n=period)

    @property
    def period(self) -> int:
        """Frames per unit now (``--summary-every``, or more when summaries got expensive)."""
        return self.core.config.every_n

    def publish_groups(self, summary: RunSummary) -> None:
        """The A* Groups of the current sequence on ``/dispeval/groups``."""
        records = group_statuses(summary, self.core.sequence)
        if records:
            stamp = self._newest if self._newest is not None else time.time_ns()
            self.groups_writer.publish(diagnostic_array(self.typestore, stamp, records))
        if self.on_summary is not None:
            self.on_summary(summary)

    def wait_for(self, received: int, timeout_s: float) -> bool:
        """Block until ``received`` score messages were taken (False on timeout)."""
        deadline = time.monotonic() + timeout_s
        with self._lock:
            while self.received < received:
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._lock.wait(left)
        return True

    # -- shutdown ----------------------------------------------------------------------------

    def finish(
        self, final: Delivery | None = None, ack_timeout_s: float = 2.0
    ) -> RunSummary | None:
        """Take what arrived, write everything, export, publish the final groups.

        ``final`` is the evaluator's final delivery record when it runs in this process
        (:meth:`DdsEvaluator.final_delivery`): its exact counts close the ledger.
        """
        if self._finished:
            return self.core.summary
        self._finished = True
        self.thread.stop(drain=True)
        with self._lock:
            if final is not None:
                self._book.ledger.add(final)
            if self.frames:
                self._book_counts(closing=True)
            summary = self.core.finish()
        if summary is not None:
            self.publish_groups(summary)
            self.groups_writer.wait_for_acks(ack_timeout_s)
        return summary

    def _book_counts(self, *, closing: bool) -> None:
        """The evaluator's counts and problems of the current sequence (under the lock)."""
        self.core.add_counts(*self._book.checkpoint(closing=closing))

    def status(self) -> dict[str, Any]:
        """Counters for a status line."""
        with self._lock:
            return {
                "received": self.received,
                "frames": self.frames,
                "ignored": self.ignored,
                "sequence": self.core.sequence,
            }


def _handle(value: int) -> int:
    """An instance handle as an unsigned 64-bit number (cyclonedds gives both signednesses)."""
    return int(value) & 0xFFFF_FFFF_FFFF_FFFF
