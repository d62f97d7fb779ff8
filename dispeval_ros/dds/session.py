"""The evaluator and the summarizer on one participant: what ``dispeval live`` runs.

The summarizer listens to ``/dispeval/scores`` like a separate node would, but only to this
session's evaluator. Stopping is ordered so nothing is lost: stop listening, score and publish
every frame still waiting, wait until the summarizer has taken every published frame, then
write the database, the CSV and ``summary.json`` (with the evaluator's unmatched, dropped and
failed counts) and publish the final groups.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from dispeval_ros.dds.evaluator import DdsEvaluator
from dispeval_ros.dds.summarizer import DdsSummarizer
from dispeval_ros.dds.transport import DdsTransport
from dispeval_ros.stream.alarms import AlarmThresholds
from dispeval_ros.stream.config import QUEUE_SIZE
from dispeval_ros.stream.core import CoreConfig, MethodCounts
from dispeval_ros.stream.summarizer import SummarizerConfig
from dispeval_ros.summary import RunSummary


@dataclass(frozen=True)
class SessionStatus:
    """Counters for the live line."""

    frames: int
    messages: int
    stored: int
    queue_drops: int
    dropped: int
    sequence: str
    restarts: int
    silent: tuple[str, ...]
    """Subscribed topics without any matched publisher (wrong domain, type or network?)."""


class LiveSession:
    """Evaluate and summarise on a DDS domain until :meth:`stop`."""

    def __init__(
        self,
        domain: int,
        config: CoreConfig,
        summary_config: SummarizerConfig,
        run_config: Mapping[str, object],
        *,
        alarms: AlarmThresholds | None = None,
        queue_size: int = QUEUE_SIZE,
        on_error: Callable[[str], None] | None = None,
        odometry: str | None = None,
        mount: Any = None,
    ) -> None:
        """``odometry``, ``mount``: see :class:`DdsEvaluator`."""
        self.transport = DdsTransport(domain)
        try:
            self.evaluator = DdsEvaluator(
                self.transport,
                config,
                alarms=alarms,
                queue_size=queue_size,
                on_error=on_error,
                odometry=odometry,
                mount=mount,
            )
            self.summarizer = DdsSummarizer(
                self.transport,
                summary_config,
                run_config,
                only_from=self.evaluator.scores_writer,
                restart_ns=2 * (config.tolerance_ns + config.lateness_ns) + 1_000_000_000,
                on_error=on_error,
            )
        except BaseException:
            self.transport.close()
            raise
        self.summary: RunSummary | None = None
        self.counts: dict[str, MethodCounts] = {}
        self.complete = True
        self._stopped = False
        self._final: SessionStatus | None = None

    def start(self) -> None:
        """Start listening (the summarizer first, so it sees the first frame)."""
        self.summarizer.start()
        self.evaluator.start()

    def status(self) -> SessionStatus:
        """What happened so far (after :meth:`stop`: at the end)."""
        if self._final is not None:
            return self._final
        summarizer = self.summarizer.status()
        return SessionStatus(
            frames=self.evaluator.published,
            messages=self.evaluator.received(),
            stored=summarizer["frames"],
            queue_drops=self.evaluator.queue_drops,
            dropped=sum(c.dropped for c in self.evaluator.counts().values()),
            sequence=summarizer["sequence"],
            restarts=self.evaluator.restarts,
            silent=tuple(r.topic for r in self.evaluator.readers if r.matched() == 0),
        )

    def stop(self, timeout_s: float = 30.0) -> RunSummary | None:
        """Flush, finish the results (complete database, CSV, summary.json), leave the domain.

        ``complete`` tells whether the summarizer got every published frame in time.
        """
        if self._stopped:
            return self.summary
        self._stopped = True
        try:
            self.evaluator.stop(flush=True)
            deadline = time.monotonic() + timeout_s
            self.complete = self.summarizer.wait_for(
                self.evaluator.published, max(0.0, deadline - time.monotonic())
            )
            final = self.evaluator.final_delivery()
            self.counts = final.counts
            self.summary = self.summarizer.finish(final)
        finally:
            self._final = self.status()
            self.transport.close()
        return self.summary
