"""The ``summarizer`` node (``dispeval_summarizer``): store the scores, group the methods.

A thin adapter over :class:`~dispeval_ros.stream.summarizer.SummarizerCore`: every
``/dispeval/scores`` array is turned back into exact :class:`~dispeval_ros.core.Scores`
(:func:`~dispeval_ros.stream.vectors.scores_from_status`, from the raw sums) and added to the
results database, the same one ``dispeval bag`` writes, with the evaluators' problems and
counts (unmatched, dropped, failed) from their delivery records
(:mod:`dispeval_ros.stream.delivery`); scored frames that never arrived are counted as dropped,
with a problem saying so. After every ``summary_every`` frames the
A* Groups are recomputed and published, latched, on ``/dispeval/groups``. ``~/new_sequence``
(``std_srvs/Trigger``) closes the current sequence and starts the next one.

On SIGINT / SIGTERM the node keeps receiving for up to ``drain_timeout`` seconds while an
evaluator is still publishing its last frames, then writes everything (``results.sqlite``,
``frames.csv``, ``summary.json``) and publishes the final groups. Files are written even if
publishing is no longer possible.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_srvs.srv import Trigger

from dispeval_ros.core import Scores
from dispeval_ros.core.egomotion import TemporalSums
from dispeval_ros.core.lidar_drift import DriftSums
from dispeval_ros.core.temporal import PairScores
from dispeval_ros.errors import DispevalError, ResultsConflictError
from dispeval_ros.io.messages import stamp_ns
from dispeval_ros.ros import convert
from dispeval_ros.ros.evaluator import SCORES_DEPTH
from dispeval_ros.ros.lifecycle import run_node
from dispeval_ros.ros.param_table import SUMMARIZER_PARAMETERS
from dispeval_ros.ros.params import declare_parameters, ros_advice, summarizer_options
from dispeval_ros.stream.delivery import CountsBook, read_delivery
from dispeval_ros.stream.flicker import FlickerScore
from dispeval_ros.stream.summarizer import SummarizerCore, group_statuses
from dispeval_ros.stream.topics import GROUPS_TOPIC, SCORES_TOPIC
from dispeval_ros.stream.vectors import (
    arrivals_of,
    read_pairs,
    read_problem,
    scores_from_status,
    window_only,
)
from dispeval_ros.summary import RunSummary

NODE_NAME = "dispeval_summarizer"
SCORES_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=SCORES_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
GROUPS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
RUN_CONFIG = {"source": NODE_NAME, "scores_topic": SCORES_TOPIC}
"""What the results database records about the run (``resume`` requires the same)."""
LOG_PERIOD = 5.0
DRAIN_POLL = 0.05
ACK_TIMEOUT = 2.0
"""Seconds to wait at shutdown for subscribers to acknowledge the final groups."""
DRAIN_QUIET_POLLS = 3
"""At shutdown: polls without a new message and without a publisher that end the drain."""


class SummarizerNode(Node):
    """``/dispeval/scores`` → :class:`SummarizerCore` → ``/dispeval/groups`` and files."""

    def __init__(self, *, stop: threading.Event | None = None, **node_options: Any) -> None:
        super().__init__(NODE_NAME, **node_options)
        self.exit_code = 0
        self.options = summarizer_options(declare_parameters(self, SUMMARIZER_PARAMETERS))
        out = self.options.config.out
        try:
            self._core = SummarizerCore(self.options.config, RUN_CONFIG)
        except ResultsConflictError as conflict:
            raise ros_advice(conflict) from None
        self._lock = threading.Lock()
        self._finished = False
        self._received = 0
        self._last_stamp = 0
        self._book = CountsBook()
        self.groups_acknowledged: bool | None = None
        """Whether subscribers acknowledged the final groups (None before shutdown)."""
        self._groups_pub = self.create_publisher(DiagnosticArray, GROUPS_TOPIC, GROUPS_QOS)
        self.create_subscription(DiagnosticArray, SCORES_TOPIC, self._on_scores, SCORES_QOS)
        self.create_service(Trigger, "~/new_sequence", self._on_new_sequence)
        self.get_logger().info(
            f"writing {out / 'results.sqlite'} (sequence {self._core.sequence}); groups every "
            f"{self.options.config.every_n} frame(s) on {GROUPS_TOPIC}"
        )

    @property
    def frames_received(self) -> int:
        """How many score arrays arrived so far (scored or not)."""
        return self._received

    @property
    def sequence(self) -> str:
        """The sequence new frames go to."""
        return self._core.sequence

    # -- input ------------------------------------------------------------------------------

    def _on_scores(self, msg: Any) -> None:
        self._received += 1
        stamp = stamp_ns(msg.header)
        frame: dict[str, Scores] = {}
        arrivals: dict[str, tuple[int, int]] = {}
        pairs: dict[str, tuple[int, PairScores]] = {}
        motion: dict[str, tuple[int, TemporalSums]] = {}
        drift: dict[str, DriftSums] = {}
        flicker: dict[str, FlickerScore] = {}
        deliveries = []
        problems: list[tuple[int | None, str | None, str]] = []
        for status in msg.status:
            record = convert.status_record(status)
            problem = read_problem(record)
            try:
                delivery = read_delivery(record)
                if delivery is not None:
                    deliveries.append(delivery)
                else:
                    if problem is not None:
                        problems.append((stamp, *problem))
                    else:
                        if not window_only(record):
                            frame[record.name] = scores_from_status(record.values)
                        read_pairs(record, pairs, motion, drift=drift, flicker=flicker)
                    arrivals.update(arrivals_of(record))  # failed estimates' too
            except DispevalError as error:
                self.get_logger().warning(
                    f"ignoring status '{record.name}' on {SCORES_TOPIC}: {error}",
                    throttle_duration_sec=LOG_PERIOD,
                )
        summary = None
        with self._lock:
            if self._finished:
                return
            for delivery in deliveries:
                self._book.ledger.add(delivery, frame)
            self._book.problems.extend(problems)
            if not frame and not arrivals and not flicker:
                return
            try:
                summary = self._core.add(
                    stamp, frame, arrivals, pairs, motion, drift=drift, flicker=flicker
                )
            except DispevalError as error:
                self._book.problems.append((stamp, None, f"cannot store the frame: {error}"))
                self.get_logger().error(
                    f"cannot store the frame at {stamp} ns: {error}",
                    throttle_duration_sec=LOG_PERIOD,
                )
                return
            self._last_stamp = stamp
        if summary is not None:
            self._publish_groups(summary)

    def _on_new_sequence(self, request: Any, response: Any) -> Any:
        """``~/new_sequence``: write the current sequence, then start the next one."""
        summary = None
        with self._lock:
            if self._finished:
                response.success = False
                response.message = "the summarizer is shutting down"
                return response
            try:
                previous = self._core.sequence
                self._store_counts(closing=False)
                name = self._core.new_sequence()
                summary = self._core.summary
                response.success = True
                response.message = f"closed {previous}; new frames go to {name}"
            except DispevalError as error:
                response.success = False
                response.message = str(error)
        self.get_logger().info(response.message)
        if summary is not None:
            self._publish_groups(summary)
        return response

    # -- output -----------------------------------------------------------------------------

    def _publish_groups(self, summary: RunSummary) -> None:
        records = group_statuses(summary)
        if not records:
            return
        try:
            self._groups_pub.publish(convert.diagnostic_array(self._last_stamp, records))
        except Exception as error:  # e.g. the context was shut down: the files still count
            self.get_logger().warning(f"cannot publish the groups: {error!r}")

    # -- shutdown ---------------------------------------------------------------------------

    def finish(self, executor: Any = None) -> None:
        """Drain the last scores, write every file, publish the final groups (idempotent).

        Call it before :meth:`destroy_node`. ``executor`` (the one spinning this node) lets the
        drain receive what evaluators publish while they shut down; without it no drain.
        """
        if self._finished:
            return
        if executor is not None:
            self._drain(executor)
        with self._lock:
            self._finished = True
            try:
                self._store_counts(closing=True)
                summary = self._core.finish()
            except DispevalError as error:
                self.get_logger().error(f"cannot complete the summary: {error}")
                self.exit_code = 2
                summary = None
            frames = self._core.frames
        out = self.options.config.out
        written = "results.sqlite, frames.csv, summary.json" if summary else "results.sqlite"
        self.get_logger().info(f"{frames} frame(s) summarized; wrote {written} in {out}")
        if summary is not None:
            self._publish_groups(summary)
            try:
                acked = self._groups_pub.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT))
            except Exception as error:  # e.g. the context is already shut down
                self.get_logger().warning(f"cannot wait for the final groups: {error!r}")
                acked = False
            self.groups_acknowledged = bool(acked)
        lost = self._book.ledger.lost_arrays()
        if lost:
            self.get_logger().warning(
                f"{lost} scored frame(s) never arrived (counted as dropped in {out})"
            )

    def _store_counts(self, *, closing: bool) -> None:
        """The evaluators' counts and problems of the current sequence (under the lock)."""
        self._core.add_counts(*self._book.checkpoint(closing=closing))

    def _drain(self, executor: Any) -> None:
        """Spin while scores keep coming or an evaluator still publishes, at most the timeout."""
        timeout = self.options.drain_timeout
        deadline = time.monotonic() + timeout
        quiet = 0
        try:
            while time.monotonic() < deadline and self.context.ok():
                before = self._received
                executor.spin_once(timeout_sec=DRAIN_POLL)
                if self._received != before or self.count_publishers(SCORES_TOPIC) > 0:
                    quiet = 0
                    continue
                quiet += 1
                if quiet >= DRAIN_QUIET_POLLS:
                    break
        except ExternalShutdownException:
            pass


def main(args: Sequence[str] | None = None) -> int:
    """``ros2 run dispeval_ros summarizer``: run the node until SIGINT / SIGTERM."""
    return run_node(lambda stop: SummarizerNode(stop=stop), NODE_NAME, args)


if __name__ == "__main__":
    raise SystemExit(main())
